"""The registry of object classes: what a scenario's entities may be.

An object class is one unit (:class:`ObjectClass`): its property schema (names, defaults,
ranges, units), the values that say what the builder makes of it (:attr:`ObjectClass.fixed`,
e.g. ``shape``), its builder, and optionally what the timeline needs to know of it
(:attr:`ObjectClass.fluid_role`). The scenario checks (:mod:`..scenario`), the world builder
(:mod:`..world`) and the timeline read the registry; none of them branches on class names.

Classes register themselves when their module is imported (:mod:`.` imports the built-in
ones); another installed package adds its own through the entry-point group
:data:`ENTRY_POINTS` (each entry point names a module that registers its classes when
imported), loaded once on first use, as Gymnasium loads environment plugins.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Callable, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation import plugins

if TYPE_CHECKING:
    from collections.abc import Mapping

    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = [
    'ENTRY_POINTS',
    'ObjectClass',
    'Property',
    'REQUIRED',
    'describe',
    'get',
    'names',
    'register',
]

ENTRY_POINTS = 'projection_server.objects'

REQUIRED = object()   # a property's default: the entity must give it

# What a property's value must be.
POSITIVE, NONNEGATIVE, FRACTION, ANY = 'positive', 'nonnegative', 'fraction', 'any'
NAME = 'name'                    # a non-empty string (a model, a link, an entity's name)
FILE = 'file'                    # a model file's path (resolved in an asset directory)
POINTS, PAIRS = 'points', 'pairs'   # lists of [x, y, z] / of [parent, child] indices
VECTOR = 'vector'                # [x, y, z]
NUMBERS, NAMES = 'numbers', 'names'   # lists of numbers / of non-empty strings

@dataclass(frozen=True)
class Property:
    """A property of an object class: its default (:data:`REQUIRED`, None for "absent
    unless given", or a value), what its values must be (:data:`POSITIVE`, ...) and its
    unit."""

    name: str
    default: Any
    kind: str
    unit: str = ''
    doc: str = ''


@dataclass(frozen=True)
class ObjectClass:
    """One class of scenario entities, as the simulator knows it.

    ``build(physics, entity)`` adds the entity's bodies (and object models) to the world;
    None for a class that another class builds (a robot's gripper). ``aliases`` are older
    property names still accepted (old name -> (name, factor)). ``check(name, properties)``
    checks what the schema cannot (raising ProjectionError). ``fluid_role(entity)`` says
    what the entity is to a particle fluid's timeline: ``('fluid', particle radius)``,
    ``('surface', (x, y), top z, radius)`` (a disc particles land on),
    ``('vessel', inner radius, inner bottom z, rim z)`` (in the body's frame) or
    ``('level', z)`` (a support whose top counts as spilled on); None: nothing.
    """

    name: str
    properties: tuple[Property, ...]
    build: Callable[[Physics, Entity], None] | None
    fixed: Mapping[str, Any] = field(default_factory=dict)
    aliases: Mapping[str, tuple[str, float]] = field(default_factory=dict)
    fluid_role: Callable[[Entity], tuple[Any, ...]] | None = None
    check: Callable[[str, dict[str, Any]], None] | None = None
    doc: str = ''

    def accepted(self) -> list[str]:
        """The property keys the simulator honours for this class (sorted; aliases left
        out)."""
        return sorted({*(p.name for p in self.properties), *self.fixed})

    def describe(self) -> dict[str, Any]:
        """The class as plain data (for Prolog and documentation)."""
        return {'class': self.name, 'doc': self.doc, 'fixed': dict(self.fixed),
                'properties': [{'name': p.name, 'unit': p.unit, 'kind': p.kind,
                                'required': p.default is REQUIRED, 'doc': p.doc,
                                'default': None if p.default is REQUIRED else p.default}
                               for p in self.properties]}


_CLASSES: plugins.Registry[ObjectClass] = plugins.Registry(
    ENTRY_POINTS, 'object class', ErrorKind.INVALID_SCENARIO,
    'unknown class {name!r} (known: {known})')


def register(cls: ObjectClass) -> ObjectClass:
    """Add ``cls`` to the registry (names are unique)."""
    return _CLASSES.register(cls)


def get(name: str) -> ObjectClass:
    """The class called ``name``.

    Raises:
        ProjectionError: kind ``invalid_scenario`` for an unknown class.
    """
    return _CLASSES.get(name)


def names() -> list[str]:
    """The registered classes' names, sorted."""
    return _CLASSES.names()


def describe() -> list[dict[str, Any]]:
    """Every class as plain data, sorted by name."""
    return [_CLASSES.get(name).describe() for name in names()]



def check_value(entity: str, key: str, value: Any, kind: str) -> Any:
    """``value`` of property ``key`` of ``entity`` checked against ``kind``, normalised
    (floats, tuples).

    Raises:
        ProjectionError: kind ``invalid_scenario``, naming the entity and key.
    """
    if kind in (POINTS, PAIRS):
        size = 3 if kind == POINTS else 2
        if not isinstance(value, (list, tuple)) or not all(
                isinstance(v, (list, tuple)) and len(v) == size and all(map(is_number, v))
                for v in value):
            _fail(f'{entity}: {key} must be a list of lists of {size} numbers')
        if kind == PAIRS:
            return [tuple(int(i) for i in v) for v in value]
        return [tuple(float(x) for x in v) for v in value]
    if kind in (NAME, FILE):
        if not isinstance(value, str) or not value:
            _fail(f'{entity}: {key} must be a non-empty string')
        return value
    if kind == VECTOR:
        if (not isinstance(value, (list, tuple)) or len(value) != 3
                or not all(map(is_number, value))):
            _fail(f'{entity}: {key} must be a list of three numbers, got {value!r}')
        return tuple(float(v) for v in value)
    if kind == NUMBERS:
        if not isinstance(value, (list, tuple)) or not all(map(is_number, value)):
            _fail(f'{entity}: {key} must be a list of numbers, got {value!r}')
        return tuple(float(v) for v in value)
    if kind == NAMES:
        if (not isinstance(value, (list, tuple)) or not value
                or not all(isinstance(v, str) and v for v in value)):
            _fail(f'{entity}: {key} must be a non-empty list of names, got {value!r}')
        return tuple(value)
    if not is_number(value):
        _fail(f'{entity}: {key} must be a finite number, got {value!r}')
    value = float(value)
    ok = {POSITIVE: value > 0, NONNEGATIVE: value >= 0, FRACTION: 0 <= value <= 1,
          ANY: True}[kind]
    if not ok:
        _fail(f'{entity}: {key} = {value} is not {kind}')
    return value


def is_number(value: Any) -> bool:
    """A finite int or float (not a bool)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _fail(message: str):
    raise ProjectionError(ErrorKind.INVALID_SCENARIO, message)
