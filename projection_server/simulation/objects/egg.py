"""``egg``: a convex ellipsoid, long axis (``length``) along its x, with the breakable
:class:`~projection_server.simulation.object_models.EggShell` object model.

A broken egg is replaced by its remains: a flat, spilled body of the same mass that the
gripper's pads no longer hold, where the egg was (its bottom where the egg's lowest point
was), falling on if the egg broke in the air, at rest if it broke against something.
No robot holds the remains (their collisions with every robot are off).
"""

from __future__ import annotations

import math
from typing import Any, Callable, TYPE_CHECKING

from projection_server.simulation.object_models import EggShell
from projection_server.simulation.objects.common import (lift_clear, orientation,
                                                        release_from_robots, surface)
from projection_server.simulation.objects.registry import (FRACTION, NONNEGATIVE, ObjectClass,
                                                           POSITIVE, Property, register,
                                                           REQUIRED)
from projection_server.simulation.physics import Body, Shape

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['EGG', 'ellipsoid_body', 'ellipsoid_vertices']

EGG_COLOR = (0.95, 0.9, 0.8, 1.0)
REMAINS_COLOR = (0.95, 0.75, 0.2, 1.0)
REMAINS_FLATNESS = 0.3   # height of a broken egg's remains relative to its diameter


def build(physics: Physics, entity: Entity) -> None:
    c, p = physics.client, entity.properties
    semi_axes = (p['length'] / 2, p['diameter'] / 2, p['diameter'] / 2)
    body = ellipsoid_body(physics, semi_axes, p['mass'], entity.pose.xyz,
                          orientation(c, entity))
    surface(c, body, p)
    c.changeDynamics(body, -1, rollingFriction=p['rolling_friction'],
                     spinningFriction=p['spinning_friction'])
    lift_clear(physics, body)
    physics.add_body(Body(entity.name, entity.cls, body, False,
                          Shape('sphere', tuple(2 * s for s in semi_axes), EGG_COLOR)))
    physics.models.append(EggShell(entity.name, semi_axes, p.get('breaking_force'),
                                   _remains_factory(semi_axes, p)))


def ellipsoid_vertices(semi_axes: tuple[float, float, float],
                       segments: tuple[int, int]) -> list[tuple[float, float, float]]:
    """Vertices of an ellipsoid: rings along x (``segments[0]``, even so that the equator is
    a ring) of ``segments[1]`` points each, plus the two poles."""
    a, b, c = semi_axes
    rings, around = segments
    vertices = [(a, 0.0, 0.0), (-a, 0.0, 0.0)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        x, s = a * math.cos(theta), math.sin(theta)
        for j in range(around):
            phi = 2 * math.pi * j / around
            vertices.append((x, b * s * math.cos(phi), c * s * math.sin(phi)))
    return vertices


def ellipsoid_body(physics: Physics, semi_axes: tuple[float, float, float], mass: float,
                   position: Any, quaternion: Any) -> int:
    """A convex hull of :func:`ellipsoid_vertices` with the ellipsoid's own inertia."""
    c = physics.client
    vertices = ellipsoid_vertices(semi_axes, physics.settings.physics.ellipsoid_segments)
    shape = c.createCollisionShape(c.GEOM_MESH, vertices=vertices)
    body = c.createMultiBody(mass, shape, -1, position, quaternion)
    a, b, cc = semi_axes
    # Bullet derives a hull's inertia from its bounding box; set the ellipsoid's own.
    c.changeDynamics(body, -1, localInertiaDiagonal=[mass * (b * b + cc * cc) / 5,
                                                     mass * (a * a + cc * cc) / 5,
                                                     mass * (a * a + b * b) / 5])
    return body


def _remains_factory(semi_axes: tuple[float, float, float],
                     props: dict[str, Any]) -> Callable[[Physics, str], None]:
    """How a broken egg is replaced (see the module doc)."""
    def replace(physics: Physics, name: str) -> None:
        c = physics.client
        old = physics.body(name).body_id
        position, quaternion = c.getBasePositionAndOrientation(old)
        velocity = (c.getBaseVelocity(old)[0] if not c.getContactPoints(bodyA=old)
                    else (0.0, 0.0, 0.0))
        bottom = c.getAABB(old)[0][2]
        yaw = c.getEulerFromQuaternion(quaternion)[2]
        flat = (semi_axes[0], semi_axes[1], semi_axes[2] * REMAINS_FLATNESS)
        flat_orientation = c.getQuaternionFromEuler((0.0, 0.0, yaw))
        body = ellipsoid_body(physics, flat, props['mass'],
                              (position[0], position[1], bottom + flat[2]), flat_orientation)
        lowest = c.getAABB(body)[0][2]   # the same collision margin as the egg's
        c.resetBasePositionAndOrientation(
            body, (position[0], position[1], bottom + flat[2] + bottom - lowest),
            flat_orientation)
        surface(c, body, props)
        c.resetBaseVelocity(body, velocity, (0.0, 0.0, 0.0))
        release_from_robots(physics, body)
        physics.replace_body(name, body, Shape('sphere', tuple(2 * s for s in flat),
                                               REMAINS_COLOR))
    return replace


EGG = register(ObjectClass(
    name='egg',
    properties=(Property('length', REQUIRED, POSITIVE, 'm', 'along the body x axis'),
                Property('diameter', REQUIRED, POSITIVE, 'm'),
                Property('mass', REQUIRED, POSITIVE, 'kg'),
                Property('friction', 0.3, NONNEGATIVE),
                Property('restitution', 0.05, FRACTION),
                Property('rolling_friction', 0.0, NONNEGATIVE, 'm'),
                Property('spinning_friction', 0.0, NONNEGATIVE, 'm'),
                Property('breaking_force', None, POSITIVE, 'N',
                         'the shell breaks at this equivalent load; absent: never')),
    fixed={'shape': 'ellipsoid'},
    build=build,
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
