"""``pancake_maker``: a flat disc (``radius``, ``height``); static with ``mass`` 0.

With ``heating`` 1 its top is held at ``temperature`` [deg C] and heats the batter that
lies on it (:mod:`projection_server.simulation.batter.heat`); with ``heating`` 0 it is
switched off and heats nothing."""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.batter.heat import ABSOLUTE_ZERO
from projection_server.simulation.objects.common import primitive
from projection_server.simulation.objects.registry import (ANY, FRACTION, NONNEGATIVE,
                                                           ObjectClass, POSITIVE, Property,
                                                           register, REQUIRED)

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


def _check(name: str, p: dict[str, Any]) -> None:
    if p['temperature'] < ABSOLUTE_ZERO:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{name}: temperature = {p["temperature"]} deg C is below '
                              'absolute zero')
    if p['heating'] not in (0.0, 1.0):
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{name}: heating must be 0 (off) or 1 (on), got {p["heating"]}')


PANCAKE_MAKER = register(ObjectClass(
    name='pancake_maker',
    properties=(Property('radius', REQUIRED, POSITIVE, 'm'),
                Property('height', REQUIRED, POSITIVE, 'm'),
                Property('mass', 0.0, NONNEGATIVE, 'kg'),
                Property('friction', 0.5, NONNEGATIVE),
                Property('restitution', 0.1, FRACTION),
                Property('temperature', 20.0, ANY, 'degC', 'surface temperature when heating'),
                Property('heating', 0.0, FRACTION, '', '1: heated to temperature, 0: off')),
    fixed={'shape': 'cylinder'},
    aliases={'diameter': ('radius', 0.5)},
    build=build,
    check=_check,
    fluid_role=_fluid_role,
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
