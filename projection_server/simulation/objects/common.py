"""What the builders of several object classes share: surfaces, poses, primitive bodies,
and lifting a spawned body clear of what it would otherwise penetrate."""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.physics import Body, Shape

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['MAX_COMPOUND_SHAPES', 'SPAWN_CLEARANCE', 'compound_shape', 'lift_clear',
           'orientation', 'primitive', 'release_from_robots', 'surface']

SPAWN_CLEARANCE = 1e-4   # m left between a spawned body and what it would otherwise touch
# PyBullet keeps at most this many shapes of one createCollisionShapeArray and silently
# drops the rest (MAX_COMPOUND_COLLISION_SHAPES of its shared-memory commands).
MAX_COMPOUND_SHAPES = 16


def compound_shape(client: Any, types: list[int], **arrays: Any) -> int:
    """``createCollisionShapeArray(types, **arrays)``, refusing more shapes than PyBullet
    keeps (a dropped shape is a hole in the body).

    Raises:
        ProjectionError: kind ``invalid_scenario`` for more than MAX_COMPOUND_SHAPES shapes.
    """
    if len(types) > MAX_COMPOUND_SHAPES:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'a body of {len(types)} collision shapes: PyBullet keeps '
                              f'only {MAX_COMPOUND_SHAPES} of one compound')
    return client.createCollisionShapeArray(types, **arrays)


def orientation(client: Any, entity: Entity) -> tuple[float, ...]:
    """The entity's orientation as a quaternion (x, y, z, w)."""
    return client.getQuaternionFromEuler(entity.pose.rpy)


def surface(client: Any, body_id: int, props: dict[str, Any]) -> None:
    """The body's friction and restitution from its properties."""
    client.changeDynamics(body_id, -1, lateralFriction=props['friction'],
                          restitution=props['restitution'])


def primitive(physics: Physics, entity: Entity, kind: str, size: tuple[float, float, float],
              color: tuple[float, float, float, float]) -> None:
    """A box or cylinder (``size``: full extents) at the entity's pose, of its mass."""
    c, p = physics.client, entity.properties
    if kind == 'box':
        shape = c.createCollisionShape(c.GEOM_BOX, halfExtents=[s / 2 for s in size])
    else:
        shape = c.createCollisionShape(c.GEOM_CYLINDER, radius=size[0] / 2, height=size[2])
    mass = p['mass']
    body = c.createMultiBody(mass, shape, -1, entity.pose.xyz, orientation(c, entity))
    surface(c, body, p)
    physics.add_body(Body(entity.name, entity.cls, body, mass == 0.0,
                          Shape(kind if kind == 'box' else 'cylinder', size, color)))


def lift_clear(physics: Physics, body_id: int) -> None:
    """Raise a newly spawned body out of any body it penetrates (a pose given as the
    nominal contact, e.g. an egg lying on the table, touches within Bullet's margins)."""
    c = physics.client
    for _ in range(4):
        depth = max((-p[8] for other in physics.bodies.values() if other.body_id != body_id
                     for p in c.getClosestPoints(body_id, other.body_id, SPAWN_CLEARANCE)),
                    default=-SPAWN_CLEARANCE)
        if depth <= -SPAWN_CLEARANCE:
            return
        position, quaternion = c.getBasePositionAndOrientation(body_id)
        c.resetBasePositionAndOrientation(
            body_id, (position[0], position[1], position[2] + depth + SPAWN_CLEARANCE),
            quaternion)


def release_from_robots(physics: Physics, body_id: int) -> None:
    """Switch off the collisions of every link of ``body_id`` with every link of every
    robot (a driven body): the broken remains of an object that no gripper or arm holds."""
    c = physics.client
    links = range(-1, c.getNumJoints(body_id))
    for robot in physics.bodies.values():
        if robot.driven:
            for robot_link in range(-1, c.getNumJoints(robot.body_id)):
                for link in links:
                    c.setCollisionFilterPair(body_id, robot.body_id, link, robot_link, 0)
