"""``robot``: built by the robot model its ``model`` names
(:mod:`projection_server.simulation.robots`): ``pr2`` with its ``gripper`` entity, if the
scenario has one (a part of the robot in the knowledge base); ``urdf`` from the facts of a
URDF or SDF arm and its gripper (:mod:`projection_server.simulation.robots.urdf_arm`)."""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from projection_server.simulation import robots
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.objects.registry import (FILE, NAME, NAMES, NUMBERS,
                                                           ObjectClass, POSITIVE, Property,
                                                           register, VECTOR)

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['ROBOT']


def build(physics: Physics, entity: Entity) -> None:
    name = entity.properties.get('gripper')
    gripper = next((e for e in physics.scenario.of_class('gripper') if e.name == name), None)
    robots.get(entity.properties['model']).build(physics, entity, gripper)


def check(name: str, properties: dict[str, Any]) -> None:
    """The model exists (before any world is built) and honours every property given."""
    model = robots.get(properties['model'])
    unknown = sorted(set(properties) - {'model', *model.properties})
    if unknown:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{name}: a {model.name} robot has no property '
                              f'{", ".join(unknown)} (it takes: '
                              f'{", ".join(["model", *model.properties])})')
    if model.check is not None:
        model.check(name, properties)


ROBOT = register(ObjectClass(
    name='robot',
    properties=(Property('model', 'pr2', NAME, '', 'the robot model that builds it'),
                Property('gripper', None, NAME, '', 'pr2: its gripper entity or asset'),
                Property('file', None, FILE, '', 'urdf: the URDF or SDF (one model)'),
                Property('tool_link', None, NAME, '', 'urdf: the link of the tool point'),
                Property('tool_offset', None, VECTOR, 'm',
                         "urdf: the tool point in the tool link's frame"),
                Property('tool_rpy', None, VECTOR, 'rad',
                         "urdf: the tool frame turned from the tool link's"),
                Property('finger_joints', None, NAMES, '', 'urdf: the fingers\' joints'),
                Property('finger_open', None, NUMBERS, 'rad',
                         'urdf: revolute finger joints\' values when open'),
                Property('finger_closed', None, NUMBERS, 'rad',
                         'urdf: revolute finger joints\' values when closed'),
                Property('pad_links', None, NAMES, '',
                         'urdf: the links that touch what the gripper holds'),
                Property('max_force', None, POSITIVE, 'N', 'urdf: the grip force limit'),
                Property('home', None, NUMBERS, 'rad or m', "urdf: the arm joints' start"),
                Property('joint_names', None, NAMES, '',
                         'urdf: the joints joint_positions gives'),
                Property('joint_positions', None, NUMBERS, 'rad or m',
                         'urdf: named joints\' start, over home')),
    fixed={'shape': 'none'},
    build=build,
    check=check,
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
