"""The physics engines a projection runs on: one protocol, one implementation per engine.

An engine (:class:`Engine`) opens a :class:`Session` per worker process (PyBullet's keeps
one warm client; MuJoCo's needs none) that builds each projection's world from its scenario
as a :class:`~projection_server.simulation.physics.Physics` of the engine: the protocol
that programs, object models and the monitor use (named queries and commands, contacts,
poses), whichever engine runs.

Where a unit builds differently on each engine (a body's shapes, a robot's joints and
motors), the engine holds one builder per unit name (``object_builder``, ``robot_builder``):
the PyBullet builders are the units' own, MuJoCo's live in :mod:`.mujoco`. A projection
that needs what an engine cannot build or run is an error before anything is projected
(:func:`check`).
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import importlib
from typing import Any, Callable, Protocol, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.settings import ENGINES

if TYPE_CHECKING:
    from projection_server.settings import Settings
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity, Scenario

__all__ = ['Engine', 'Session', 'check', 'get']


class Session(Protocol):
    """An engine opened in one process, building one world after the other."""

    def build_world(self, scenario: Scenario, settings: Settings,
                    tool_control: bool = False) -> Physics:
        """A fresh world of ``scenario`` at ``settings``."""

    def close(self) -> None:
        """Free the engine's resources."""


@dataclass(frozen=True)
class Engine:
    """A physics engine: how to open it, and its builders of object classes and robot
    models (None: the engine cannot build that unit).

    ``copyable``: its whole world lives in the process's objects, so a deep copy of a
    projection, then ``after_copy()`` on the copy's physics, goes on exactly as the
    original would (projections that part copy it where they part: :mod:`~projection_server.
    simulation.branching`). PyBullet's world lives in its server: it is not."""

    name: str
    open: Callable[[], Session]
    object_builder: Callable[[str], Callable[[Any, Entity], None] | None]
    robot_builder: Callable[[str], Callable[..., None] | None]
    copyable: bool = False


@functools.cache
def get(name: str) -> Engine:
    """The engine called ``name`` (one of :data:`~projection_server.settings.ENGINES`).

    Raises:
        ProjectionError: kind ``invalid_settings`` for an unknown engine.
    """
    if name not in ENGINES:
        raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                              f'unknown physics engine {name!r} (engines: {", ".join(ENGINES)})')
    return importlib.import_module(f'{__name__}.{name}').ENGINE


def check(engine: str, program: str, scenario: Scenario) -> None:
    """``program`` can run on ``engine`` in ``scenario``: the program's task and every
    entity's builder exist for the engine.

    Raises:
        ProjectionError: kind ``invalid_settings``, naming the program (or the entity and
        its class or robot model) and the engine.
    """
    from projection_server.simulation.objects import get as object_class
    from projection_server.simulation.programs import get as get_program

    unit = get(engine)
    runs_on = get_program(program).engines
    if engine not in runs_on:
        raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                              f'the program {program} cannot run on the {engine} engine '
                              f'(it runs on: {", ".join(runs_on)})')
    for entity in scenario.entities:
        if object_class(entity.cls).build is None:
            continue   # built by the entity that owns it (a gripper by its robot)
        if unit.object_builder(entity.cls) is None:
            raise ProjectionError(
                ErrorKind.INVALID_SETTINGS, f'{program}: the {engine} engine cannot build '
                f'{entity.name} (a {entity.cls})')
        model = entity.properties.get('model') if entity.cls == 'robot' else None
        if model is not None and unit.robot_builder(model) is None:
            raise ProjectionError(
                ErrorKind.INVALID_SETTINGS, f'{program}: the {engine} engine cannot build '
                f'the robot {entity.name} (model {model})')
