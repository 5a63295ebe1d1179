"""``spatula``: a box, the blade (the turning program moves it as a hand would, so no
handle or arm is simulated)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from projection_server.simulation.objects.common import primitive
from projection_server.simulation.objects.registry import (FRACTION, NONNEGATIVE, ObjectClass,
                                                           POSITIVE, Property, register,
                                                           REQUIRED)

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['SPATULA']


def build(physics: Physics, entity: Entity) -> None:
    p = entity.properties
    primitive(physics, entity, 'box', (p['size_x'], p['size_y'], p['size_z']),
              (0.5, 0.5, 0.55, 1.0))


SPATULA = register(ObjectClass(
    name='spatula',
    properties=(Property('size_x', REQUIRED, POSITIVE, 'm'),
                Property('size_y', REQUIRED, POSITIVE, 'm'),
                Property('size_z', REQUIRED, POSITIVE, 'm'),
                Property('mass', REQUIRED, POSITIVE, 'kg'),
                Property('friction', 0.4, NONNEGATIVE),
                Property('restitution', 0.1, FRACTION)),
    fixed={'shape': 'box'},
    build=build,
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
