"""Checked, typed form of a scenario description (the dict of ``docs/contracts.md``).

Pure Python, so the parent process can reject a bad scenario before a worker is involved.
What each class accepts is its unit's schema in the object class registry
(:mod:`projection_server.simulation.objects`).

Tolerance rules for the knowledge base's dicts:

* Parts of an entity (``parts``) are flattened into the scenario; their poses are in the world.
* A missing ``pose`` is the identity pose; a missing ``properties`` is empty.
* Every property acts on the simulation or is refused: a key that is neither a property of
  the entity's class nor one of its ``fixed`` keys is an error naming the entity, the key
  and the accepted keys (:func:`accepted_properties`). ``fixed`` keys describe what the
  builder makes of a class (``shape``, a static body's ``mass`` 0); another value than the
  one given there is an error.
* Properties with a default may be left out; those without one are required.
* A class's ``aliases`` (older keys such as ``diameter``, ``count``) stand in for its
  properties (``radius``, ``particle_count``) when those are missing.
* Numbers may be ints or floats; every physical quantity must be finite and in its range.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation import objects
from projection_server.simulation.objects.registry import check_value, FILE, is_number, REQUIRED

if TYPE_CHECKING:
    from collections.abc import Iterator, Mapping

    from projection_server.simulation.objects import ObjectClass

__all__ = [
    'Entity',
    'Pose',
    'Scenario',
    'accepted_properties',
    'model_files',
    'parse_scenario',
]


def accepted_properties(cls: str) -> list[str]:
    """The property keys the simulator honours for class ``cls`` (sorted; aliases left
    out); [] for an unknown class."""
    return objects.get(cls).accepted() if cls in objects.names() else []


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

    @property
    def unit(self) -> ObjectClass:
        """The entity's object class: its schema, builder and timeline roles."""
        return objects.get(self.cls)


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


def model_files(scenario: Scenario) -> list[str]:
    """The model files the entities of ``scenario`` name (their file-valued properties),
    sorted, each once."""
    return sorted({entity.properties[prop.name] for entity in scenario.entities
                   for prop in entity.unit.properties
                   if prop.kind == FILE and prop.name in entity.properties})


def _collect(item: Any, out: list[Entity], where: str) -> None:
    if not isinstance(item, dict):
        _fail(f'{where}: an entity must be a dict')
    name, cls = item.get('name'), item.get('class')
    if not isinstance(name, str) or not name:
        _fail(f'{where}: entity without a name')
    if not isinstance(cls, str) or cls not in objects.names():
        _fail(f'{name}: unknown class {cls!r} (known: {", ".join(objects.names())})')
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
            or not all(is_number(v) for v in value)):
        _fail(f'{name}: {key} must be a list of three finite numbers, got {value!r}')
    return tuple(float(v) for v in value)


def _properties(name: str, cls: str, given: Mapping[str, Any]) -> dict[str, Any]:
    unit = objects.get(cls)
    values: dict[str, Any] = {}
    given = dict(given)
    for old, (key, factor) in unit.aliases.items():
        if key not in given and old in given:
            given[key] = given[old] * factor if is_number(given[old]) else given[old]
    accepted = unit.accepted()
    for key in sorted(set(given) - set(accepted) - set(unit.aliases)):
        _fail(f'{name}: {cls} has no property {key!r} that the simulator honours '
              f'(accepted: {", ".join(accepted)})')
    for key, fixed in unit.fixed.items():
        if key in given and given[key] != fixed and not (
                is_number(given[key]) and is_number(fixed) and given[key] == fixed):
            _fail(f'{name}: {cls} property {key!r} must be {fixed!r} (the simulator builds '
                  f'a {cls} as that), got {given[key]!r}')
    for prop in unit.properties:
        value = given.get(prop.name, prop.default)
        if value is REQUIRED:
            _fail(f'{name}: {cls} property {prop.name!r} is missing')
        if value is not None:
            values[prop.name] = check_value(name, prop.name, value, prop.kind)
    if unit.check is not None:
        unit.check(name, values)
    return values


def _fail(message: str):
    raise ProjectionError(ErrorKind.INVALID_SCENARIO, message)
