"""``pancake_maker``: a flat disc (``radius``, ``height``); static with ``mass`` 0."""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from projection_server.simulation.objects.common import primitive
from projection_server.simulation.objects.registry import (FRACTION, NONNEGATIVE, ObjectClass,
                                                           POSITIVE, Property, register,
                                                           REQUIRED)

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['PANCAKE_MAKER']


def build(physics: Physics, entity: Entity) -> None:
    p = entity.properties
    primitive(physics, entity, 'cylinder', (2 * p['radius'], 2 * p['radius'], p['height']),
              (0.2, 0.2, 0.2, 1.0))


def _fluid_role(entity: Entity) -> tuple[Any, ...]:
    x, y, z = entity.pose.xyz
    p = entity.properties
    return ('surface', (x, y), z + p['height'] / 2, p['radius'])


PANCAKE_MAKER = register(ObjectClass(
    name='pancake_maker',
    properties=(Property('radius', REQUIRED, POSITIVE, 'm'),
                Property('height', REQUIRED, POSITIVE, 'm'),
                Property('mass', 0.0, NONNEGATIVE, 'kg'),
                Property('friction', 0.5, NONNEGATIVE),
                Property('restitution', 0.1, FRACTION)),
    fixed={'shape': 'cylinder'},
    aliases={'diameter': ('radius', 0.5)},
    build=build,
    fluid_role=_fluid_role,
    doc=__doc__.splitlines()[0],
))
