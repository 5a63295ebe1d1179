"""Units from other installed packages: entry-point groups, loaded once per process.

A package adds object classes, robot models or control programs by naming, in one of the
groups below, a module that registers them when imported (as Gymnasium's environment
plugins do)::

    # the plugin's pyproject.toml
    [project.entry-points."projection_server.objects"]
    kettle = "my_kitchen.kettle"
"""

from __future__ import annotations

from importlib import metadata
import logging
import threading
from typing import Any, Generic, TypeVar

from projection_server.errors import ErrorKind, ProjectionError

__all__ = ['GROUPS', 'Registry', 'load']

GROUPS = ('projection_server.objects', 'projection_server.robots',
          'projection_server.programs')

_log = logging.getLogger(__name__)
_loaded: set[str] = set()
_lock = threading.Lock()


def load(group: str) -> None:
    """Import the modules of entry-point ``group`` of every installed package, once per
    process. A plugin that fails to import is logged and left out."""
    if group in _loaded:
        return
    with _lock:
        if group in _loaded:
            return
        _loaded.add(group)
        for entry_point in metadata.entry_points(group=group):
            try:
                entry_point.load()
            except Exception as exc:  # noqa: BLE001 - one broken plugin must not stop all
                _log.error('plugin %s of %s failed to load: %s: %s', entry_point.name,
                           group, type(exc).__name__, exc)


T = TypeVar('T')


class Registry(Generic[T]):
    """Units of one kind by name (each has a ``name``), with those of the entry-point
    ``group`` loaded before the first lookup.

    ``unknown`` is the message for a name not registered, with ``{name!r}`` and ``{known}``;
    ``kind`` the error kind it is raised with.
    """

    def __init__(self, group: str, noun: str, kind: ErrorKind, unknown: str):
        self.group, self._noun, self._kind, self._unknown = group, noun, kind, unknown
        self._units: dict[str, T] = {}

    def register(self, unit: T) -> T:
        """Add ``unit`` (names are unique)."""
        name = unit.name  # type: ignore[attr-defined]
        if name in self._units:
            raise ValueError(f'{self._noun} {name!r} is registered already')
        self._units[name] = unit
        return unit

    def get(self, name: Any) -> T:
        """The unit called ``name``.

        Raises:
            ProjectionError: of the registry's kind, for an unknown name.
        """
        load(self.group)
        try:
            return self._units[name]
        except (KeyError, TypeError):
            raise ProjectionError(self._kind, self._unknown.format(
                name=name, known=', '.join(sorted(self._units)))) from None

    def names(self) -> list[str]:
        """The registered names, sorted."""
        load(self.group)
        return sorted(self._units)
