"""Warming a worker up: one throw-away projection before its first job.

The first projection of a fresh process costs 2-3 times a later one (imports on first use,
rosbags' per-type serializers, the code digest, the first world's assets); a worker pays
that here, when it starts or is replaced, rather than in a query's first projection. The
projection (``warm_up.yaml`` beside this module) runs into a temporary directory that is
deleted: nothing reaches the bag directory, and a warm worker's bags are those of a fresh
one (every projection sets all engine parameters itself).
"""

from __future__ import annotations

import functools
from pathlib import Path
import shutil
import time
from typing import Any, TYPE_CHECKING

from projection_server.workers.bag_store import private_tmp_dir

if TYPE_CHECKING:
    from projection_server.simulation.runner import Simulator
    from projection_server.settings import Settings

__all__ = ['WARM_UP_FILE', 'warm_up', 'warm_up_job']

WARM_UP_FILE = Path(__file__).with_name('warm_up.yaml')


@functools.cache
def _description() -> dict[str, Any]:
    import yaml

    return yaml.safe_load(WARM_UP_FILE.read_text(encoding='utf-8'))


def warm_up_job():
    """The warm-up projection as a checked :class:`~projection_server.simulation.job.Job`."""
    from projection_server.simulation.job import Job

    data = _description()
    return Job.checked(data['scenario'], data['program'], data['params'])


def warm_up(simulator: Simulator, settings: Settings) -> dict[str, Any]:
    """Run the warm-up projection on ``simulator``; ``{'seconds': s, 'error': None}``, or
    the error's text instead of raising (a worker that could not warm up still serves)."""
    start = time.perf_counter()
    tmp = private_tmp_dir('projection-warm-up-')
    try:
        from projection_server.workers.run import project

        project(simulator, warm_up_job(), settings, tmp / 'bag')
    except Exception as exc:  # noqa: BLE001 - reported, the worker serves regardless
        return {'seconds': time.perf_counter() - start,
                'error': f'{type(exc).__name__}: {exc}'}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {'seconds': time.perf_counter() - start, 'error': None}
