"""``robot``: built by the robot model its ``model`` names
(:mod:`projection_server.simulation.robots`), with its ``gripper`` entity, if the scenario
has one (a part of the robot in the knowledge base)."""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from projection_server.simulation import robots
from projection_server.simulation.objects.registry import NAME, ObjectClass, Property, register

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['ROBOT']


def build(physics: Physics, entity: Entity) -> None:
    name = entity.properties['gripper']
    gripper = next((e for e in physics.scenario.of_class('gripper') if e.name == name), None)
    robots.get(entity.properties['model']).build(physics, entity, gripper)


def check(name: str, properties: dict[str, Any]) -> None:
    robots.get(properties['model'])   # an unknown model is refused before any world is built


ROBOT = register(ObjectClass(
    name='robot',
    properties=(Property('model', 'pr2', NAME, '', 'the robot model that builds it'),
                Property('gripper', 'pr2_gripper', NAME, '', 'its gripper entity or asset')),
    fixed={'shape': 'none'},
    build=build,
    check=check,
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
