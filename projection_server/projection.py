"""Entry point of the simulation side for Prolog: ``simulate``, ``submit``, ``programs``.

One process-wide :class:`~projection_server.simulation.pool.WorkerPool`, created on first
use with the settings given to :func:`configure` (default bag directory: the environment
variable ``PROJECTION_SERVER_BAG_DIR``, else ``~/.cache/projection_server/bags``).

    >>> path = simulate(scenario, 'grasp_object', {'force': 5.0, 'position': 0.0}, 60.0)
    >>> timeline = translate_bag(path)   # projection_server.timeline.translate
"""

from __future__ import annotations

import atexit
import os
from pathlib import Path
import threading
from typing import Any, TYPE_CHECKING

from projection_server.simulation import programs as _programs
from projection_server.simulation.errors import ProjectionError
from projection_server.simulation.job import Job
from projection_server.simulation.pool import Retention, WorkerPool

if TYPE_CHECKING:
    from collections.abc import Mapping
    from concurrent.futures import Future

__all__ = [
    'ProjectionError',
    'configure',
    'default_bag_dir',
    'prefetch',
    'programs',
    'shutdown',
    'simulate',
    'submit',
    'workers',
]

_lock = threading.Lock()
_pool: WorkerPool | None = None
_config: dict[str, Any] = {'bag_dir': None, 'workers': 1, 'retention': None}


def default_bag_dir() -> Path:
    """``$PROJECTION_SERVER_BAG_DIR``, else ``~/.cache/projection_server/bags``."""
    configured = os.environ.get('PROJECTION_SERVER_BAG_DIR')
    if configured:
        return Path(configured).expanduser()
    return Path.home() / '.cache' / 'projection_server' / 'bags'


def configure(bag_dir: str | os.PathLike[str] | None = None, workers: int | None = None,
              retention: Retention | Mapping[str, Any] | None = None) -> None:
    """Set where bags go, how many workers run projections and how many bags are kept.

    Arguments left as None keep their current value. ``retention`` is a
    :class:`~projection_server.simulation.pool.Retention` or a dict with ``max_bags`` and
    ``max_bytes``. A running pool is closed; the next projection starts a new one.
    """
    global _pool
    with _lock:
        if workers is not None and (not isinstance(workers, int) or workers < 1):
            raise ProjectionError('invalid_settings', f'workers must be >= 1, got {workers!r}')
        updates = {'bag_dir': bag_dir, 'workers': workers,
                   'retention': Retention.of(retention) if retention is not None else None}
        _config.update({k: v for k, v in updates.items() if v is not None})
        old, _pool = _pool, None
    if old is not None:
        old.close()


def simulate(scenario: dict[str, Any], program: str, params: dict[str, Any],
             timeout: float) -> str:
    """Run one projection in a supervised worker and return the path of its bag.

    ``timeout`` is the wall-clock limit of the simulation in seconds. An identical
    projection made before (same scenario, program, parameters, settings and code) returns
    the existing bag.

    Raises:
        ProjectionError: with ``kind`` ``invalid_scenario``, ``unknown_program``,
            ``invalid_parameters``, ``timeout``, ``worker_crashed``, ``simulation_failed``...
    """
    job = Job.checked(scenario, program, params)
    return _get_pool().run(job, timeout)


def submit(scenario: dict[str, Any], program: str, params: dict[str, Any],
           timeout: float) -> Future[str]:
    """Like :func:`simulate`, but return at once with a future of the bag path.

    For running a query's parametrizations ahead of Prolog's backtracking; a later
    :func:`simulate` of the same projection waits for the same future.
    """
    job = Job.checked(scenario, program, params)
    return _get_pool().submit(job, timeout)


def prefetch(scenario: dict[str, Any], program: str, params_list: list[dict[str, Any]],
             timeout: float) -> int:
    """Queue projections that a query will probably ask for next; return how many.

    Lets the workers run a query's next parametrizations while Prolog is still
    evaluating the current one. Invalid ones are skipped here: :func:`simulate`
    reports their errors when (and if) they are asked for.
    """
    queued = 0
    for params in params_list:
        try:
            submit(scenario, program, params, timeout)
            queued += 1
        except ProjectionError:
            pass
    return queued


def workers() -> int:
    """Number of simulation workers (the useful prefetch depth)."""
    return int(_config['workers'])


def programs() -> list[dict[str, Any]]:
    """The registered control programs with their formal parameters (name, unit, min, max,
    default)."""
    return _programs.describe()


def shutdown() -> None:
    """Stop the process-wide pool (also done at exit)."""
    global _pool
    with _lock:
        old, _pool = _pool, None
    if old is not None:
        old.close()


def _get_pool() -> WorkerPool:
    global _pool
    with _lock:
        if _pool is None:
            _pool = WorkerPool(_config['bag_dir'] or default_bag_dir(),
                               workers=_config['workers'], retention=_config['retention'])
        return _pool


atexit.register(shutdown)
