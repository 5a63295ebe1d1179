"""Physics, control, logging and timeline settings, read from ``config/physics.yaml``.

The settings are part of every projection's cache key and are recorded in its bag, so the
translation of a bag uses the timeline thresholds the bag was made with.

The engine settings of :data:`PHYSICS_OPTIONS` can be chosen per engine and per program (the
``engines`` and ``programs`` sections of the file) and per query
(``make_projection(..., [physics(_{...})], TL)``); a projection uses
``settings.for_projection(program, physics)``: the file's settings, then its engine's, then
the program's, then the query's. A finer time step keeps the control and logging rates::

    >>> load_settings().for_projection('grasp_object', {'rate_hz': 960}).control
    ControlSettings(steps_per_control=16, steps_per_log=16)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, MISSING, replace
import functools
import math
import os
from pathlib import Path
from typing import Any

from projection_server.canonical import canonical_json
from projection_server.errors import ErrorKind, ProjectionError

__all__ = [
    'ControlSettings',
    'PHYSICS_OPTIONS',
    'PhysicsOption',
    'PhysicsSettings',
    'Settings',
    'TimelineSettings',
    'ENGINES',
    'check_physics',
    'config_path',
    'describe_physics',
    'load_settings',
]

CONFIG_NAME = 'physics.yaml'
# The physics engines a projection may run on (``physics(_{engine: E})``); the first is the
# default of the settings file. A bag made before engines could be chosen is PyBullet's.
ENGINES = ('pybullet', 'mujoco')


@dataclass(frozen=True)
class PhysicsSettings:
    """Settings of the physics engine (``engine``: one of :data:`ENGINES`; the others are
    PyBullet's names, MuJoCo reads what it has of them: rate, gravity, iterations)."""

    rate_hz: int
    gravity: tuple[float, float, float]
    solver_iterations: int
    erp: float
    contact_erp: float
    friction_erp: float
    contact_breaking_threshold: float
    solver_residual_threshold: float
    deterministic_overlapping_pairs: int
    ellipsoid_segments: tuple[int, int]
    engine: str = ENGINES[0]

    @property
    def time_step(self) -> float:
        return 1.0 / self.rate_hz


@dataclass(frozen=True)
class ControlSettings:
    """Integer ratios of physics steps to control and to monitoring steps."""

    steps_per_control: int
    steps_per_log: int


@dataclass(frozen=True)
class TimelineSettings:
    """Thresholds of the translation of bags into timelines, in physical units (see
    ``config/physics.yaml``)."""

    gap_merge: float            # s
    contact_force_min: float    # N
    support_max_angle: float    # rad
    slip_distance: float        # m
    slip_angle: float           # rad
    grasp_settle: float         # s
    drop_min_fall: float        # m
    tip_angle: float            # rad

    @classmethod
    def recorded(cls, data: Mapping[str, Any], current: TimelineSettings | None = None
                 ) -> TimelineSettings:
        """The settings a bag recorded (``data``, its ``settings_json['timeline']``). A bag
        made before a setting existed is read with ``current``'s value of it (default: the
        settings file's); settings no longer used are ignored (``drop_min_duration`` [s] of
        bags made before a drop was a fall of ``drop_min_fall`` [m])."""
        names = [f.name for f in fields(cls)]
        values = {name: data[name] for name in names if name in data}
        if len(values) < len(names):
            current = current if current is not None else load_settings().timeline
            values = {name: values.get(name, getattr(current, name)) for name in names}
        return cls(**{name: float(value) for name, value in values.items()})


@dataclass(frozen=True)
class PhysicsOption:
    """An engine setting a program or a query may choose, within ``[min, max]``."""

    name: str
    unit: str
    min: float
    max: float
    integer: bool
    doc: str
    values: tuple[str, ...] = ()   # a setting that names one of these, not a number

    def describe(self, default: Any) -> dict[str, Any]:
        if self.values:
            return {'name': self.name, 'unit': self.unit, 'values': list(self.values),
                    'default': default, 'doc': self.doc}
        return {'name': self.name, 'unit': self.unit, 'min': self.min, 'max': self.max,
                'integer': self.integer, 'default': default, 'doc': self.doc}


PHYSICS_OPTIONS: dict[str, PhysicsOption] = {o.name: o for o in (
    PhysicsOption('engine', '', 0, 0, False,
                  'the physics engine that runs the projection', values=ENGINES),
    PhysicsOption('rate_hz', 'Hz', 60, 4800, True,
                  'physics steps per simulated second; a multiple of the control and '
                  'logging rates, which stay as they are'),
    PhysicsOption('solver_iterations', '', 1, 2000, True,
                  'constraint solver iterations per step (at most)'),
    PhysicsOption('solver_residual_threshold', '', 0.0, 0.01, False,
                  'the solver stops iterating once its residual is below this'),
    PhysicsOption('erp', '', 0.0, 1.0, False, 'error reduction of joints'),
    PhysicsOption('contact_erp', '', 0.0, 1.0, False, 'error reduction of contacts'),
    PhysicsOption('friction_erp', '', 0.0, 1.0, False, 'error reduction of friction'),
    PhysicsOption('contact_breaking_threshold', 'm', 0.0001, 0.05, False,
                  'contact points further apart than this are dropped'),
)}


@dataclass(frozen=True)
class Settings:
    """Everything besides the scenario, program and parameters that shapes a projection.

    ``engines`` maps an engine's name to the :data:`PHYSICS_OPTIONS` values its projections
    run with instead of ``physics``'s, and ``programs`` a program's name to those it runs
    with on any engine; :meth:`for_projection` gives the settings of one projection.
    """

    physics: PhysicsSettings
    control: ControlSettings
    timeline: TimelineSettings
    programs: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    engines: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-able form (tuples become lists; no ``programs`` or ``engines`` key
        when empty, as in a projection's settings)."""
        data = _jsonable(asdict(self))
        for section in ('programs', 'engines'):
            if not data[section]:
                del data[section]
        # PyBullet's projections keep the keys and bags they had before there was a choice.
        if data['physics']['engine'] == ENGINES[0]:
            del data['physics']['engine']
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Settings:
        """Check and convert a mapping of the form of ``config/physics.yaml``."""
        sections = {'physics': PhysicsSettings, 'control': ControlSettings,
                    'timeline': TimelineSettings}
        _check_keys('settings', {k: v for k, v in data.items()
                                 if k not in ('programs', 'engines')}, sections)
        settings = cls(**{name: _section(name, section, data[name])
                          for name, section in sections.items()})
        checked: dict[str, dict[str, dict[str, Any]]] = {}
        for part in ('programs', 'engines'):
            entries = data.get(part) or {}
            if not isinstance(entries, dict):
                raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'{part}: expected a mapping')
            checked[part] = {}
            for name, overrides in entries.items():
                where = f'{part}.{name}'
                if part == 'engines' and name not in ENGINES:
                    raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'{where}: not an engine; '
                                          f'the engines: {", ".join(ENGINES)}')
                values = check_physics(overrides, settings.control_hz, where=where)
                if part == 'engines' and 'engine' in values:
                    raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                                          f'{where}: an engine\'s settings choose no engine')
                checked[part][str(name)] = values
        return replace(settings, **checked)

    @property
    def control_hz(self) -> int:
        """Least common multiple of the control and logging rates [Hz]: ``rate_hz`` must be
        a multiple of it."""
        rate, control = self.physics.rate_hz, self.control
        return math.lcm(rate // math.gcd(rate, control.steps_per_control),
                        rate // math.gcd(rate, control.steps_per_log))

    def for_projection(self, program: str,
                       physics: Mapping[str, Any] | None = None) -> Settings:
        """The settings of one projection of ``program``: its engine's physics options (the
        engine ``physics`` or the program chooses, else these settings'), the program's,
        then ``physics`` (a query's, checked here), over these settings. Idempotent."""
        own = self.programs.get(program, {})
        query = check_physics(physics or {}, self.control_hz)
        engine = query.get('engine') or own.get('engine') or self.physics.engine
        overrides = {**self.engines.get(engine, {}), **own, **query}
        base = self.physics
        values = {**{name: getattr(base, name) for name in PHYSICS_OPTIONS}, **overrides}
        rate = values['rate_hz']
        control = ControlSettings(
            steps_per_control=self.control.steps_per_control * rate // base.rate_hz,
            steps_per_log=self.control.steps_per_log * rate // base.rate_hz)
        return Settings(replace(base, **values), control, self.timeline)

    def projection_json(self, program: str,
                        physics: Mapping[str, Any] | None = None) -> str:
        """Canonical JSON of :meth:`for_projection`'s ``to_dict()``, kept per program and
        physics: a part of every projection's key."""
        wanted = (program, tuple(sorted((physics or {}).items())))
        text = self._projection_json.get(wanted)
        if text is None:
            text = canonical_json(self.for_projection(program, physics).to_dict())
            if len(self._projection_json) < 256:
                self._projection_json[wanted] = text
        return text

    @functools.cached_property
    def _projection_json(self) -> dict[tuple[Any, ...], str]:
        return {}

    def describe_physics(self, program: str | None = None,
                         engine: str | None = None) -> list[dict[str, Any]]:
        """The :data:`PHYSICS_OPTIONS` with their ranges and defaults (``program``'s, on
        ``engine`` or these settings' engine)."""
        chosen = {'engine': engine} if engine is not None else None
        defaults = self.for_projection(program or '', chosen)
        described = [option.describe(getattr(defaults.physics, name))
                     for name, option in PHYSICS_OPTIONS.items()]
        for entry in described:
            if entry['name'] == 'rate_hz':
                entry['multiple_of'] = defaults.control_hz
        return described


def check_physics(overrides: Any, control_hz: int = 1,
                  where: str = 'physics') -> dict[str, Any]:
    """``overrides`` as a dict of :data:`PHYSICS_OPTIONS` values, or ProjectionError of kind
    ``invalid_settings`` naming the first bad setting and its accepted range (``rate_hz``
    must also be a multiple of ``control_hz``)."""
    if not isinstance(overrides, Mapping):
        raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'{where}: expected a mapping of settings')
    checked = {}
    for name, value in overrides.items():
        option = PHYSICS_OPTIONS.get(str(name))
        if option is None:
            raise ProjectionError(
                ErrorKind.INVALID_SETTINGS, f'{where}: unknown physics setting {name!r}; '
                f'accepted: {", ".join(PHYSICS_OPTIONS)}')
        if option.values:
            if value not in option.values:
                raise ProjectionError(
                    ErrorKind.INVALID_SETTINGS, f'{where}: {name} must be one of '
                    f'{", ".join(option.values)}, got {value!r}')
            checked[str(name)] = str(value)
            continue
        kind = int if option.integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, kind):
            what = 'an integer' if option.integer else 'a number'
            raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                                  f'{where}: {name} must be {what}, got {value!r}')
        if not option.min <= value <= option.max:
            raise ProjectionError(
                ErrorKind.INVALID_SETTINGS,
                f'{where}: {name} must be in [{option.min:g}, {option.max:g}], got {value!r}')
        if name == 'rate_hz' and value % control_hz:
            raise ProjectionError(
                ErrorKind.INVALID_SETTINGS, f'{where}: rate_hz must be a multiple of {control_hz} '
                f'(the control and logging rates), got {value!r}')
        checked[str(name)] = int(value) if option.integer else float(value)
    return checked


def describe_physics(program: str | None = None,
                     engine: str | None = None) -> list[dict[str, Any]]:
    """:meth:`Settings.describe_physics` of the settings file."""
    return load_settings().describe_physics(program, engine)


def config_path() -> Path:
    """The settings file: a source checkout's ``config/`` first, else the installed share dir."""
    checkout = Path(__file__).resolve().parents[2] / 'config' / CONFIG_NAME
    if checkout.is_file():
        return checkout
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('projection_server'))
    except (ImportError, LookupError) as exc:
        raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'{CONFIG_NAME} not found: {exc}') from exc
    return share / 'config' / CONFIG_NAME


def load_settings(path: str | os.PathLike[str] | None = None) -> Settings:
    """Read the settings from ``path`` (default: :func:`config_path`)."""
    import yaml

    path = Path(path) if path is not None else config_path()
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'cannot read {path}: {exc}') from exc
    if not isinstance(data, dict):
        raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'{path}: expected a mapping')
    return Settings.from_dict(data)


def _section(name: str, cls: type, data: Any) -> Any:
    if not isinstance(data, dict):
        raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'{name}: expected a mapping')
    types = {f.name: f.type for f in fields(cls)}
    optional = {f.name for f in fields(cls) if f.default is not MISSING}
    _check_keys(name, {**{k: None for k in optional}, **data}, types)
    values = {}
    for key, typ in types.items():
        if key not in data:
            continue
        value = data[key]
        try:
            if typ == 'str':
                if key == 'engine' and value not in ENGINES:
                    raise ValueError(f'one of {", ".join(ENGINES)}, got {value!r}')
                values[key] = str(value)
            elif typ.startswith('tuple'):
                item = float if 'float' in typ else int
                values[key] = tuple(item(v) for v in value)
            else:
                values[key] = {'int': int, 'float': float}[typ](value)
        except (TypeError, ValueError) as exc:
            raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'{name}.{key}: {exc}') from exc
    return cls(**values)


def _check_keys(name: str, data: Mapping[str, Any], expected: Mapping[str, Any]) -> None:
    missing = sorted(set(expected) - set(data))
    unknown = sorted(set(data) - set(expected))
    if missing or unknown:
        raise ProjectionError(
            ErrorKind.INVALID_SETTINGS, f'{name}: missing keys {missing}, unknown keys {unknown}')


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value
