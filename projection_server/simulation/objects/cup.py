"""``cup``: an open container, a compound of a bottom disc (``wall_thickness`` thick) and
:data:`CUP_SEGMENTS` wall boxes on a circle, ``radius`` and ``height`` outside, origin at its
centre; its inside is registered in :attr:`Physics.containers` (a particle fluid may fill
it)."""

from __future__ import annotations

import math
from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.objects.common import (compound_shape, MAX_COMPOUND_SHAPES,
                                                         orientation, surface)
from projection_server.simulation.objects.registry import (FRACTION, NONNEGATIVE, ObjectClass,
                                                           POSITIVE, Property, register,
                                                           REQUIRED)
from projection_server.simulation.physics import Body, Container, Shape

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['CUP', 'CUP_SEGMENTS']

# Wall boxes of a cup: with its bottom, as many shapes as PyBullet keeps in one compound
# (with 16 boxes it dropped the last, and batter ran out of the slot it left).
CUP_SEGMENTS = MAX_COMPOUND_SHAPES - 1


def build(physics: Physics, entity: Entity) -> None:
    c, p = physics.client, entity.properties
    radius, height, wall = p['radius'], p['height'], p['wall_thickness']
    if wall >= radius or wall >= height:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: wall_thickness must be below radius and height')
    half_angle = math.pi / CUP_SEGMENTS
    mid = radius - wall / 2
    types, radii, extents, lengths, positions, orientations = [], [], [], [], [], []
    types.append(c.GEOM_CYLINDER)
    radii.append(radius)
    extents.append([0.0, 0.0, 0.0])
    lengths.append(wall)
    positions.append([0.0, 0.0, -height / 2 + wall / 2])
    orientations.append([0.0, 0.0, 0.0, 1.0])
    for k in range(CUP_SEGMENTS):
        phi = 2 * half_angle * k
        types.append(c.GEOM_BOX)
        radii.append(0.0)
        # Tangential half length reaches the outer circle's chord, so the wall has no gaps.
        extents.append([wall / 2, radius * math.tan(half_angle), height / 2])
        lengths.append(0.0)
        positions.append([mid * math.cos(phi), mid * math.sin(phi), 0.0])
        orientations.append(list(c.getQuaternionFromEuler((0.0, 0.0, phi))))
    shape = compound_shape(
        c, types, radii=radii, halfExtents=extents, lengths=lengths,
        collisionFramePositions=positions, collisionFrameOrientations=orientations)
    body = c.createMultiBody(p['mass'], shape, -1, entity.pose.xyz, orientation(c, entity))
    surface(c, body, p)
    physics.add_body(Body(entity.name, entity.cls, body, p['mass'] == 0.0,
                          Shape('cylinder', (2 * radius, 2 * radius, height),
                                (0.9, 0.9, 0.95, 0.4))))
    physics.containers[entity.name] = Container(*_inside(entity))


def _inside(entity: Entity) -> tuple[float, float, float]:
    """Inner radius, inner bottom z and rim z, in the cup's frame [m]."""
    p = entity.properties
    wall = p['wall_thickness']
    return p['radius'] - wall, -p['height'] / 2 + wall, p['height'] / 2


def _fluid_role(entity: Entity) -> tuple[Any, ...]:
    return ('vessel', *_inside(entity))


CUP = register(ObjectClass(
    name='cup',
    properties=(Property('radius', REQUIRED, POSITIVE, 'm', 'outside'),
                Property('height', REQUIRED, POSITIVE, 'm', 'outside'),
                Property('wall_thickness', 0.004, POSITIVE, 'm'),
                Property('mass', REQUIRED, NONNEGATIVE, 'kg'),
                Property('friction', 0.5, NONNEGATIVE),
                Property('restitution', 0.1, FRACTION)),
    fixed={'shape': 'cup'},
    aliases={'diameter': ('radius', 0.5)},
    build=build,
    fluid_role=_fluid_role,
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
