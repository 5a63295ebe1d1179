"""``table``: a static slab ``size_x`` x ``size_y`` x ``size_z`` whose top is at ``height``
(default: the pose's z), centred at the pose's x, y, turned by its yaw. Legs are not built."""

from __future__ import annotations

from typing import TYPE_CHECKING

from projection_server.simulation.objects.common import surface
from projection_server.simulation.objects.registry import (FRACTION, NONNEGATIVE, ObjectClass,
                                                           POSITIVE, Property, register,
                                                           REQUIRED)
from projection_server.simulation.physics import Body, Shape

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['TABLE', 'top']


def top(entity: Entity) -> float:
    """Height of the table's top surface [m]."""
    return entity.properties.get('height', entity.pose.xyz[2])


def build(physics: Physics, entity: Entity) -> None:
    c, p = physics.client, entity.properties
    size = (p['size_x'], p['size_y'], p['size_z'])
    shape = c.createCollisionShape(c.GEOM_BOX, halfExtents=[s / 2 for s in size])
    position = (entity.pose.xyz[0], entity.pose.xyz[1], top(entity) - size[2] / 2)
    yaw = c.getQuaternionFromEuler((0.0, 0.0, entity.pose.rpy[2]))
    body = c.createMultiBody(0.0, shape, -1, position, yaw)
    surface(c, body, p)
    physics.add_body(Body(entity.name, entity.cls, body, True,
                          Shape('box', size, (0.6, 0.4, 0.2, 1.0))))


TABLE = register(ObjectClass(
    name='table',
    properties=(Property('size_x', REQUIRED, POSITIVE, 'm'),
                Property('size_y', REQUIRED, POSITIVE, 'm'),
                Property('size_z', REQUIRED, POSITIVE, 'm'),
                Property('height', None, NONNEGATIVE, 'm', 'top surface; default: pose z'),
                Property('friction', 0.6, NONNEGATIVE),
                Property('restitution', 0.1, FRACTION)),
    fixed={'shape': 'box', 'mass': 0.0},
    build=build,
    fluid_role=lambda entity: ('level', top(entity)),
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
