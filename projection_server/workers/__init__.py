"""Who runs projections: the worker backend seam and its backends.

Map of the package:

* :mod:`.backend`: :class:`WorkerBackend`, the interface the projection layer talks to
  (submit a job -> future of a :class:`ProjectionResult`; cancel; close).
* :mod:`.base`: what every backend shares (bag store, requests, ``submit``, ``cancel``)
  and the scheduling policy: one record per worker in a named state (``WorkerState``),
  fair turns, trees, pausing, time limits, failures, replacement. Backends only transport.
* :mod:`.bag_store`: the bag directory shared by every backend (names, retention).
* :mod:`.requests`: the projections asked for, by job key and owner (every backend's).
* :mod:`.process`: the worker process of both backends (a warm simulator, its trees).
* :mod:`.messages`: the named commands and answers on a worker process's pipe.
* :mod:`.warm_up`: the throw-away projection a worker runs before its first job.
* :mod:`.local`: the ``local`` backend, supervised worker processes on this machine.
* :mod:`.ray`: the ``ray`` backend, Ray actors on this machine or a Ray cluster.
"""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.workers.backend import ProjectionResult, WorkerBackend
from projection_server.workers.bag_store import BagStore, Retention

if TYPE_CHECKING:
    import os

__all__ = ['BACKENDS', 'BagStore', 'ProjectionResult', 'Retention', 'WorkerBackend',
           'create_backend']

BACKENDS = ('local', 'ray')


def create_backend(name: str, bag_dir: str | os.PathLike[str], workers: int,
                   **options: Any) -> WorkerBackend:
    """The backend called ``name`` with ``workers`` workers writing into ``bag_dir``.

    Raises:
        ProjectionError: kind ``invalid_settings`` for an unknown backend.
    """
    if name == 'local':
        from projection_server.workers.local import WorkerPool

        return WorkerPool(bag_dir, workers=workers, **options)
    if name == 'ray':
        from projection_server.workers.ray import RayBackend

        return RayBackend(bag_dir, workers=workers, **options)
    raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                          f'unknown projection backend {name!r} (known: {", ".join(BACKENDS)})')
