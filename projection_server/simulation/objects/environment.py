"""``environment``: the world's gravity; its parts (floor, table) are entities of their own."""

from __future__ import annotations

from typing import TYPE_CHECKING

from projection_server.simulation.objects.registry import (NONNEGATIVE, ObjectClass, Property,
                                                           register)

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['ENVIRONMENT']


def build(physics: Physics, entity: Entity) -> None:
    """The world's gravity (m/s^2 along -z); without it, ``config/physics.yaml``'s holds."""
    gravity = entity.properties.get('gravity')
    if gravity is not None:
        physics.client.setGravity(0.0, 0.0, -gravity)


ENVIRONMENT = register(ObjectClass(
    name='environment',
    properties=(Property('gravity', None, NONNEGATIVE, 'm/s^2',
                         'acts along -z; default: config/physics.yaml'),),
    build=build,
    doc=__doc__.splitlines()[0],
))
