"""Checked, typed form of a scenario description (the dict of ``docs/contracts.md``).

Pure Python, so the parent process can reject a bad scenario before a worker is involved.

Tolerance rules for the knowledge base's dicts:

* Parts of an entity (``parts``) are flattened into the scenario; their poses are in the world.
* A missing ``pose`` is the identity pose; a missing ``properties`` is empty.
* Every property acts on the simulation or is refused: a key that is neither in
  :data:`PROPERTIES` nor in :data:`FIXED` for the entity's class is an error naming the
  entity, the key and the accepted keys (:func:`accepted_properties`). :data:`FIXED` keys
  describe what the builder makes of a class (``shape``, a static body's ``mass`` 0, the
  robot's ``model``); another value than the one given there is an error.
* Listed properties with a default may be left out; those without one are required.
* Older keys of :data:`ALIASES` (``diameter``, ``count``) stand in for the knowledge base's
  (``radius``, ``particle_count``) when those are missing.
* Numbers may be ints or floats; every physical quantity must be finite and in its range.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError

if TYPE_CHECKING:
    from collections.abc import Iterator, Mapping

__all__ = [
    'ALIASES',
    'CLASSES',
    'Entity',
    'FIXED',
    'PROPERTIES',
    'Pose',
    'Scenario',
    'accepted_properties',
    'parse_scenario',
]

REQUIRED = object()
_POSITIVE, _NONNEGATIVE, _FRACTION, _ANY = 'positive', 'nonnegative', 'fraction', 'any'
_POINTS, _PAIRS = 'points', 'pairs'   # lists of [x, y, z] / of [parent, child] indices

# class -> property -> (default or REQUIRED, range). Defaults are documented values of the
# builder, used only when the knowledge base leaves a property out.
PROPERTIES: dict[str, dict[str, tuple[Any, str]]] = {
    'environment': {
        'gravity': (None, _NONNEGATIVE),     # m/s^2 along -z; default: config/physics.yaml
    },
    'floor': {
        'friction': (0.8, _NONNEGATIVE),
        'restitution': (0.0, _FRACTION),
    },
    'table': {
        'size_x': (REQUIRED, _POSITIVE),
        'size_y': (REQUIRED, _POSITIVE),
        'size_z': (REQUIRED, _POSITIVE),
        'height': (None, _NONNEGATIVE),       # top surface height; default: pose z
        'friction': (0.6, _NONNEGATIVE),
        'restitution': (0.1, _FRACTION),
    },
    'robot': {
        'gripper': ('pr2_gripper', 'name'),
    },
    # A robot's gripper, given as a part of it (the robot's `gripper` names it). Its
    # friction is the pads' rubber; urdf names the asset (assets/<stem>.urdf + .yaml).
    'gripper': {
        'urdf': ('pr2_gripper.urdf', 'name'),
        'friction': (0.8, _NONNEGATIVE),
        'restitution': (0.0, _FRACTION),
        'max_force': (80.0, _POSITIVE),
        'max_opening': (0.09, _POSITIVE),
    },
    'egg': {
        'length': (REQUIRED, _POSITIVE),
        'diameter': (REQUIRED, _POSITIVE),
        'mass': (REQUIRED, _POSITIVE),
        'friction': (0.3, _NONNEGATIVE),
        'restitution': (0.05, _FRACTION),
        'rolling_friction': (0.0, _NONNEGATIVE),
        'spinning_friction': (0.0, _NONNEGATIVE),
        'breaking_force': (None, _POSITIVE),  # None: the shell does not break
    },
    # An open container: a bottom disc and a wall, ``radius`` and ``height`` outside.
    'cup': {
        'radius': (REQUIRED, _POSITIVE),
        'height': (REQUIRED, _POSITIVE),
        'wall_thickness': (0.004, _POSITIVE),
        'mass': (REQUIRED, _NONNEGATIVE),
        'friction': (0.5, _NONNEGATIVE),
        'restitution': (0.1, _FRACTION),
    },
    'pancake_maker': {
        'radius': (REQUIRED, _POSITIVE),
        'height': (REQUIRED, _POSITIVE),
        'mass': (0.0, _NONNEGATIVE),
        'friction': (0.5, _NONNEGATIVE),
        'restitution': (0.1, _FRACTION),
    },
    'pancake': {
        'radius': (REQUIRED, _POSITIVE),
        'thickness': (REQUIRED, _POSITIVE),
        'mass': (REQUIRED, _POSITIVE),
        'friction': (0.5, _NONNEGATIVE),
        'restitution': (0.0, _FRACTION),
        # The deformable model (projection_server.simulation.pancake): "rings" (a centre
        # disc and rings of segments) or "particles" (one segment per given offset).
        'model': ('rings', 'name'),
        'joint_stiffness': (0.05, _POSITIVE),   # N m/rad
        'joint_damping': (0.001, _NONNEGATIVE),   # N m s/rad
        'joint_radius': (0.015, _POSITIVE),     # m
        'ring_count': (3, _POSITIVE),
        'segment_count': (8, _POSITIVE),
        'particles': (None, _POINTS),
        'joints': (None, _PAIRS),
    },
    'spatula': {
        'size_x': (REQUIRED, _POSITIVE),
        'size_y': (REQUIRED, _POSITIVE),
        'size_z': (REQUIRED, _POSITIVE),
        'mass': (REQUIRED, _POSITIVE),
        'friction': (0.4, _NONNEGATIVE),
        'restitution': (0.1, _FRACTION),
    },
    # Spheres; with a ``container`` (an entity built before, e.g. the owning cup) they fill
    # it from its bottom, without one they form a cubic block at the pose.
    'particle_fluid': {
        'particle_count': (REQUIRED, _POSITIVE),
        'particle_radius': (REQUIRED, _POSITIVE),
        'particle_mass': (REQUIRED, _POSITIVE),
        'friction': (0.1, _NONNEGATIVE),
        'restitution': (0.0, _FRACTION),
        'rolling_friction': (0.0, _NONNEGATIVE),
        'spinning_friction': (0.0, _NONNEGATIVE),
        'damping': (5.0, _NONNEGATIVE),
        'container': (None, 'name'),
    },
}
# Older keys still accepted where the knowledge base's key is missing:
# class -> old key -> (key of the knowledge base, factor).
ALIASES: dict[str, dict[str, tuple[str, float]]] = {
    'cup': {'diameter': ('radius', 0.5)},
    'pancake_maker': {'diameter': ('radius', 0.5)},
    'pancake': {'diameter': ('radius', 0.5), 'height': ('thickness', 1.0)},
    'particle_fluid': {'count': ('particle_count', 1.0)},
}
# Keys that say what the builder makes of a class, with the one value it accepts.
FIXED: dict[str, dict[str, Any]] = {
    'environment': {},
    'floor': {'shape': 'plane', 'mass': 0.0},
    'table': {'shape': 'box', 'mass': 0.0},
    'robot': {'shape': 'none', 'model': 'pr2'},
    'gripper': {'shape': 'urdf'},
    'egg': {'shape': 'ellipsoid'},
    'cup': {'shape': 'cup'},
    'pancake_maker': {'shape': 'cylinder'},
    'pancake': {'shape': 'disc'},
    'spatula': {'shape': 'box'},
    'particle_fluid': {'shape': 'sphere'},
}
CLASSES = frozenset(PROPERTIES)


def accepted_properties(cls: str) -> list[str]:
    """The property keys the simulator honours for class ``cls`` (sorted; aliases left
    out); [] for an unknown class."""
    return sorted({*PROPERTIES.get(cls, {}), *FIXED.get(cls, {})})


@dataclass(frozen=True)
class Pose:
    """Position [m] and roll/pitch/yaw [rad] in the world frame."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Entity:
    """One entity of a scenario with its class's properties, defaults filled in."""

    name: str
    cls: str
    pose: Pose
    properties: Mapping[str, Any]


@dataclass(frozen=True)
class Scenario:
    """A checked scenario: a name and its entities, parts flattened, in the given order."""

    name: str
    entities: tuple[Entity, ...]

    def of_class(self, cls: str) -> Iterator[Entity]:
        """The entities of class ``cls``, in scenario order."""
        return (e for e in self.entities if e.cls == cls)


def parse_scenario(data: Any) -> Scenario:
    """Check a scenario description and return its typed form.

    Raises:
        ProjectionError: kind ``invalid_scenario``, naming the offending entity and key.
    """
    if not isinstance(data, dict):
        _fail(f'expected a dict, got {type(data).__name__}')
    name = data.get('name', 'scenario')
    if not isinstance(name, str) or not name:
        _fail('name must be a non-empty string')
    raw = data.get('entities')
    if not isinstance(raw, list) or not raw:
        _fail('entities must be a non-empty list')
    entities: list[Entity] = []
    for item in raw:
        _collect(item, entities, where='entities')
    seen: set[str] = set()
    for entity in entities:
        if entity.name in seen:
            _fail(f'entity name {entity.name!r} is used twice')
        seen.add(entity.name)
    return Scenario(name, tuple(entities))


def _collect(item: Any, out: list[Entity], where: str) -> None:
    if not isinstance(item, dict):
        _fail(f'{where}: an entity must be a dict')
    name, cls = item.get('name'), item.get('class')
    if not isinstance(name, str) or not name:
        _fail(f'{where}: entity without a name')
    if cls not in CLASSES:
        _fail(f'{name}: unknown class {cls!r} (known: {", ".join(sorted(CLASSES))})')
    props = item.get('properties', {})
    if not isinstance(props, dict):
        _fail(f'{name}: properties must be a dict')
    out.append(Entity(name, cls, _pose(name, item.get('pose')), _properties(name, cls, props)))
    parts = item.get('parts', [])
    if not isinstance(parts, list):
        _fail(f'{name}: parts must be a list')
    for part in parts:
        _collect(part, out, where=f'{name}.parts')


def _pose(name: str, pose: Any) -> Pose:
    if pose is None:
        return Pose()
    if not isinstance(pose, dict):
        _fail(f'{name}: pose must be a dict with xyz and rpy')
    return Pose(_vector(name, 'pose.xyz', pose.get('xyz', [0, 0, 0])),
                _vector(name, 'pose.rpy', pose.get('rpy', [0, 0, 0])))


def _vector(name: str, key: str, value: Any) -> tuple[float, float, float]:
    if (not isinstance(value, (list, tuple)) or len(value) != 3
            or not all(_is_number(v) for v in value)):
        _fail(f'{name}: {key} must be a list of three finite numbers, got {value!r}')
    return tuple(float(v) for v in value)


def _properties(name: str, cls: str, given: Mapping[str, Any]) -> dict[str, Any]:
    values: dict[str, Any] = {}
    given = dict(given)
    aliases = ALIASES.get(cls, {})
    for old, (key, factor) in aliases.items():
        if key not in given and old in given:
            given[key] = given[old] * factor if _is_number(given[old]) else given[old]
    accepted = accepted_properties(cls)
    for key in sorted(set(given) - set(accepted) - set(aliases)):
        _fail(f'{name}: {cls} has no property {key!r} that the simulator honours '
              f'(accepted: {", ".join(accepted)})')
    for key, fixed in FIXED[cls].items():
        if key in given and given[key] != fixed and not (
                _is_number(given[key]) and _is_number(fixed) and given[key] == fixed):
            _fail(f'{name}: {cls} property {key!r} must be {fixed!r} (the simulator builds '
                  f'a {cls} as that), got {given[key]!r}')
    for key, (default, kind) in PROPERTIES[cls].items():
        value = given.get(key, default)
        if value is REQUIRED:
            _fail(f'{name}: {cls} property {key!r} is missing')
        if value is not None:
            values[key] = _checked(name, key, value, kind)
    return values


def _checked(name: str, key: str, value: Any, kind: str) -> Any:
    if kind in (_POINTS, _PAIRS):
        size = 3 if kind == _POINTS else 2
        if not isinstance(value, (list, tuple)) or not all(
                isinstance(v, (list, tuple)) and len(v) == size and all(map(_is_number, v))
                for v in value):
            _fail(f'{name}: {key} must be a list of lists of {size} numbers')
        if kind == _PAIRS:
            return [tuple(int(i) for i in v) for v in value]
        return [tuple(float(x) for x in v) for v in value]
    if kind == 'name':
        if not isinstance(value, str) or not value:
            _fail(f'{name}: {key} must be a non-empty string')
        return value
    if not _is_number(value):
        _fail(f'{name}: {key} must be a finite number, got {value!r}')
    value = float(value)
    ok = {_POSITIVE: value > 0, _NONNEGATIVE: value >= 0, _FRACTION: 0 <= value <= 1,
          _ANY: True}[kind]
    if not ok:
        _fail(f'{name}: {key} = {value} is not {kind}')
    return value


def _is_number(value: Any) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _fail(message: str):
    raise ProjectionError(ErrorKind.INVALID_SCENARIO, message)
