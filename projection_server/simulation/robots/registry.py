"""The registry of robot models: how a scenario's ``robot`` entity becomes bodies and the
actuators a program drives.

A robot model is one unit (:class:`RobotModel`): a name (the robot entity's ``model``) and
a builder. Its data (URDF, and a YAML description of what a program needs of it: joints,
tool, finger pads, limits) lives in ``assets/`` beside this module. Models register
themselves when their module is imported; another installed package adds its own through
the entry-point group :data:`ENTRY_POINTS`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, TYPE_CHECKING

from projection_server.errors import ErrorKind
from projection_server.simulation import plugins

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['ENTRY_POINTS', 'RobotModel', 'assets_dir', 'get', 'names', 'register']

ENTRY_POINTS = 'projection_server.robots'

@dataclass(frozen=True)
class RobotModel:
    """A robot model: ``build(physics, robot, gripper)`` adds the robot's bodies and
    actuators to the world for the ``robot`` entity; ``gripper`` is the entity of its
    gripper when the scenario describes it (its friction and limits come from there).

    ``properties`` are the robot entity's properties the model honours (besides ``model``);
    ``check(name, properties)`` checks them before any world is built."""

    name: str
    build: Callable[[Physics, Entity, Entity | None], None]
    properties: tuple[str, ...] = ()
    check: Callable[[str, dict[str, Any]], None] | None = None
    doc: str = ''


_MODELS: plugins.Registry[RobotModel] = plugins.Registry(
    ENTRY_POINTS, 'robot model', ErrorKind.INVALID_SCENARIO,
    'unknown robot model {name!r} (known: {known})')


def assets_dir() -> Path:
    """Directory of the robot models' data files (URDF, their YAML descriptions)."""
    return Path(__file__).with_name('assets')


def register(model: RobotModel) -> RobotModel:
    """Add ``model`` to the registry (names are unique)."""
    return _MODELS.register(model)


def get(name: str) -> RobotModel:
    """The robot model called ``name``.

    Raises:
        ProjectionError: kind ``invalid_scenario`` for an unknown model.
    """
    return _MODELS.get(name)


def names() -> list[str]:
    """The registered models' names, sorted."""
    return _MODELS.names()
