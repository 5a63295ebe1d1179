"""``floor``: a static plane at the pose's z."""

from __future__ import annotations

from typing import TYPE_CHECKING

from projection_server.simulation.objects.common import surface
from projection_server.simulation.objects.registry import (FRACTION, NONNEGATIVE, ObjectClass,
                                                           Property, register)
from projection_server.simulation.physics import Body, Shape

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['FLOOR']


def build(physics: Physics, entity: Entity) -> None:
    c = physics.client
    shape = c.createCollisionShape(c.GEOM_PLANE)
    body = c.createMultiBody(0.0, shape, -1, (0.0, 0.0, entity.pose.xyz[2]))
    surface(c, body, entity.properties)
    physics.add_body(Body(entity.name, entity.cls, body, True,
                          Shape('box', (20.0, 20.0, 0.001), (0.5, 0.5, 0.5, 1.0))))


FLOOR = register(ObjectClass(
    name='floor',
    properties=(Property('friction', 0.8, NONNEGATIVE),
                Property('restitution', 0.0, FRACTION)),
    fixed={'shape': 'plane', 'mass': 0.0},
    build=build,
    doc=__doc__.splitlines()[0],
))
