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

__all__ = ['GROUPS', 'load']

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
