"""Where a projection's time goes, for benchmarks (``bench/decision_cost.py``).

With the environment variable ``PROJECTION_SERVER_COST_LOG`` set to a file, the node and its
worker processes append one JSON line per event to it (one ``write`` on an ``O_APPEND``
file each, so lines of several processes do not mix); unset, :func:`record` does nothing
and costs a test of a module constant. Events name the projection by its bag's name:

* ``queued``, in the node: a projection was queued (``t``: wall-clock time);
* ``sent`` and ``answered``, in the node: its command went to a worker, its answer came
  back (after the bag was published);
* ``projected``, in a worker: ``start`` and ``end`` of its handling (wall-clock), the CPU
  seconds of :meth:`Simulator.run` (``sim_cpu``), of the timeline (``timeline_cpu``) and of
  the whole handling up to the answer sent (``cpu``).
"""

from __future__ import annotations

import json
import os
from typing import Any

__all__ = ['PATH', 'record']

PATH = os.environ.get('PROJECTION_SERVER_COST_LOG') or None


def record(event: str, bag: str, **fields: Any) -> None:
    """Append ``event`` of the projection whose bag is named ``bag`` (if the log is on)."""
    if PATH is None:
        return
    line = json.dumps({'event': event, 'bag': os.path.basename(bag), 'pid': os.getpid(),
                       **fields}) + '\n'
    fd = os.open(PATH, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, line.encode())
    finally:
        os.close(fd)
