"""Physics, control, logging and timeline settings, read from ``config/physics.yaml``.

The settings are part of every projection's cache key and are recorded in its bag, so the
translation of a bag uses the timeline thresholds the bag was made with.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
import os
from pathlib import Path
from typing import Any, TYPE_CHECKING

from projection_server.simulation.errors import ProjectionError

if TYPE_CHECKING:
    from collections.abc import Mapping

__all__ = [
    'ControlSettings',
    'PhysicsSettings',
    'Settings',
    'TimelineSettings',
    'config_path',
    'load_settings',
]

CONFIG_NAME = 'physics.yaml'


@dataclass(frozen=True)
class PhysicsSettings:
    """Settings of the PyBullet engine."""

    rate_hz: int
    gravity: tuple[float, float, float]
    solver_iterations: int
    erp: float
    contact_erp: float
    friction_erp: float
    contact_breaking_threshold: float
    deterministic_overlapping_pairs: int
    ellipsoid_segments: tuple[int, int]

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
    """Thresholds of the translation of bags into timelines (see ``config/physics.yaml``)."""

    gap_merge: float
    contact_force_min: float
    support_max_angle: float
    slip_distance: float
    slip_angle: float
    grasp_settle: float
    drop_min_duration: float


@dataclass(frozen=True)
class Settings:
    """Everything besides the scenario, program and parameters that shapes a projection."""

    physics: PhysicsSettings
    control: ControlSettings
    timeline: TimelineSettings

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-able form (tuples become lists)."""
        return _jsonable(asdict(self))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Settings:
        """Check and convert a mapping of the form of ``config/physics.yaml``."""
        sections = {'physics': PhysicsSettings, 'control': ControlSettings,
                    'timeline': TimelineSettings}
        _check_keys('settings', data, sections)
        return cls(**{name: _section(name, section, data[name])
                      for name, section in sections.items()})


def config_path() -> Path:
    """The settings file: a source checkout's ``config/`` first, else the installed share dir."""
    checkout = Path(__file__).resolve().parents[2] / 'config' / CONFIG_NAME
    if checkout.is_file():
        return checkout
    try:
        from ament_index_python.packages import get_package_share_directory
        share = Path(get_package_share_directory('projection_server'))
    except (ImportError, LookupError) as exc:
        raise ProjectionError('invalid_settings', f'{CONFIG_NAME} not found: {exc}') from exc
    return share / 'config' / CONFIG_NAME


def load_settings(path: str | os.PathLike[str] | None = None) -> Settings:
    """Read the settings from ``path`` (default: :func:`config_path`)."""
    import yaml

    path = Path(path) if path is not None else config_path()
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ProjectionError('invalid_settings', f'cannot read {path}: {exc}') from exc
    if not isinstance(data, dict):
        raise ProjectionError('invalid_settings', f'{path}: expected a mapping')
    return Settings.from_dict(data)


def _section(name: str, cls: type, data: Any) -> Any:
    if not isinstance(data, dict):
        raise ProjectionError('invalid_settings', f'{name}: expected a mapping')
    types = {f.name: f.type for f in fields(cls)}
    _check_keys(name, data, types)
    values = {}
    for key, typ in types.items():
        value = data[key]
        try:
            if typ.startswith('tuple'):
                item = float if 'float' in typ else int
                values[key] = tuple(item(v) for v in value)
            else:
                values[key] = {'int': int, 'float': float}[typ](value)
        except (TypeError, ValueError) as exc:
            raise ProjectionError('invalid_settings', f'{name}.{key}: {exc}') from exc
    return cls(**values)


def _check_keys(name: str, data: Mapping[str, Any], expected: Mapping[str, Any]) -> None:
    missing = sorted(set(expected) - set(data))
    unknown = sorted(set(data) - set(expected))
    if missing or unknown:
        raise ProjectionError(
            'invalid_settings', f'{name}: missing keys {missing}, unknown keys {unknown}')


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value
