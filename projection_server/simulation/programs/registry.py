"""Registry of robot control programs and their formal parameters."""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Callable, Protocol, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation import plugins

if TYPE_CHECKING:
    from collections.abc import Mapping

    import numpy as np

    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Scenario

__all__ = ['ENTRY_POINTS', 'Parameter', 'Program', 'Task', 'describe', 'get', 'register']

# Programs of other installed packages (projection_server.simulation.plugins).
ENTRY_POINTS = 'projection_server.programs'


@dataclass(frozen=True)
class Parameter:
    """A formal parameter of a program: a number in ``[min, max]`` measured in ``unit``."""

    name: str
    unit: str
    min: float
    max: float
    default: float
    doc: str = ''

    def describe(self) -> dict[str, Any]:
        return {'name': self.name, 'unit': self.unit, 'min': self.min, 'max': self.max,
                'default': self.default, 'doc': self.doc}


class Task(Protocol):
    """One run of a program in a world: called at every control step until ``duration``.

    A task may also have ``finished(physics) -> bool``, asked after every monitoring
    sample: the projection ends at the first sample at which it is true.

    The task of a program with ``setup_params`` also has ``command_at(params, step)``, what
    it would command for the step after ``step`` with the parameters ``params`` (hashable:
    equal commands are equal values; asked when the world is at ``step``, so it may depend
    on the world), and ``retarget(params)``, which makes it go on with
    ``params`` from the current step. ``params`` then differ from the task's own only in
    parameters that are not set-up parameters, and ``finished`` is false until the commands
    of any two such parametrizations have differed.
    """

    duration: float

    def control(self, physics: Physics) -> None:
        """Set the actuators' commands for the current control step."""


@dataclass(frozen=True)
class Program:
    """A registered control program: name, formal parameters and a task factory.

    ``create(physics, scenario, params, rng)`` sets the program's robot up in a freshly built
    world and returns its :class:`Task`; ``rng`` is seeded from the projection's key.

    ``setup_params`` names the parameters that act when the world is set up; the others act
    only through the task's commands (nor does such a program draw from ``rng``: it is
    seeded from one projection's key). Parametrizations that agree in them step alike until
    their commands part, so they can share those steps
    (:mod:`projection_server.simulation.branching`). None (the default): the program does not
    say, and each parametrization runs from the start. A program whose shared steps cost
    less than a fork and the pages its child copies (a grasp's 0.8 s of 3.8) does not
    ``forks``: its parametrizations share steps only on an engine whose worlds copy in the
    process (``Engine.copyable``).

    A program that ``takes_plan`` (``plan``) is given the job's plan as ``create(...,
    plan=plan)``; its parameters are the plan's, any names, and it drives robots through
    their tool (``build_world``'s ``tool_control``). It is no named program
    (:func:`describe` leaves it out). ``engines`` are the physics engines it runs on.
    """

    name: str
    params: tuple[Parameter, ...]
    create: Callable[..., Task]
    doc: str = ''
    setup_params: tuple[str, ...] | None = None
    # Whether what its parametrizations share is worth a fork of a process (below).
    forks: bool = True
    takes_plan: bool = False
    # The engines whose protocol the program's task needs no more than (``engines``).
    engines: tuple[str, ...] = ('pybullet',)

    def check(self, values: Mapping[str, Any]) -> dict[str, float]:
        """Actual parameter values: given ones checked against their ranges, defaults added.

        Raises:
            ProjectionError: kind ``invalid_parameters``.
        """
        if not isinstance(values, dict):
            raise ProjectionError(ErrorKind.INVALID_PARAMETERS, 'parameters must be a dict')
        if self.takes_plan:
            return _plan_values(values)
        known = {p.name: p for p in self.params}
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ProjectionError(
                ErrorKind.INVALID_PARAMETERS,
                f'{self.name} has no parameter {", ".join(unknown)} (has: {", ".join(known)})')
        checked = {}
        for name, param in known.items():
            value = values.get(name, param.default)
            if (isinstance(value, bool) or not isinstance(value, (int, float))
                    or not math.isfinite(value)):
                raise ProjectionError(ErrorKind.INVALID_PARAMETERS,
                                      f'{self.name}: {name} must be a number, got {value!r}')
            if not param.min <= value <= param.max:
                raise ProjectionError(
                    ErrorKind.INVALID_PARAMETERS,
                    f'{self.name}: {name} = {value} {param.unit} is outside '
                    f'[{param.min}, {param.max}]')
            checked[name] = float(value)
        return checked

    def shares_steps(self, engine: str) -> bool:
        """Whether parametrizations may share their first steps on ``engine``: the program
        names its set-up parameters, and forks, or the engine's worlds copy.

        Raises:
            ProjectionError: kind ``invalid_settings`` for an unknown engine.
        """
        from projection_server.simulation import engines

        return self.setup_params is not None and (self.forks or engines.get(engine).copyable)

    def setup(self, values: Mapping[str, float]) -> tuple[float, ...] | None:
        """The set-up parameters' values of checked ``values``: parametrizations with equal
        ones (and the same scenario and settings) may share steps. None if they may not."""
        if self.setup_params is None:
            return None
        return tuple(values[name] for name in self.setup_params)

    def describe(self) -> dict[str, Any]:
        return {'program': self.name, 'doc': self.doc,
                'params': [p.describe() for p in self.params]}


_PROGRAMS: plugins.Registry[Program] = plugins.Registry(
    ENTRY_POINTS, 'program', ErrorKind.UNKNOWN_PROGRAM, 'no program {name!r} (known: {known})')


def register(program: Program) -> Program:
    """Add ``program`` to the registry (names are unique)."""
    return _PROGRAMS.register(program)


def get(name: str) -> Program:
    """The program called ``name``.

    Raises:
        ProjectionError: kind ``unknown_program``.
    """
    return _PROGRAMS.get(name)


def describe() -> list[dict[str, Any]]:
    """Every program with its formal parameters, for Prolog (sorted by name)."""
    return [program.describe() for program in map(get, _PROGRAMS.names())
            if not program.takes_plan]


def _plan_values(values: Mapping[str, Any]) -> dict[str, float]:
    """A plan's parameter values: any names, finite numbers of any sign."""
    checked = {}
    for name, value in values.items():
        if not isinstance(name, str) or not name:
            raise ProjectionError(ErrorKind.INVALID_PARAMETERS,
                                  f'a parameter name must be a non-empty string: {name!r}')
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or not math.isfinite(value)):
            raise ProjectionError(ErrorKind.INVALID_PARAMETERS,
                                  f'plan: {name} must be a number, got {value!r}')
        checked[name] = float(value)
    return checked
