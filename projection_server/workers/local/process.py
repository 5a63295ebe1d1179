"""The worker process of the ``local`` backend: one warm simulator, commands over a pipe.

Start-up pays once what every projection would otherwise pay again: imports, the PyBullet
connection, message type registration and asset parsing, and a throw-away projection for
what only a first projection sets up (:mod:`projection_server.workers.warm_up`); the ready
message says how long that took. A ``project`` command is answered with
``(result, ok)``; a projection's result is its timeline, made from the samples the worker
has in memory (:mod:`projection_server.timeline.translate`). A ``tree`` command (projections
that share their first steps, :mod:`projection_server.simulation.branching`) is answered
with ``(index, result, ok)`` for each projection as it ends, then ``(None, complete, True)``,
where ``complete`` is False if a process of the tree crashed before it reported.
"""

from __future__ import annotations

import os
from pathlib import Path
import traceback
from typing import Any

from projection_server.simulation.errors import ProjectionError

__all__ = ['worker_main']


def worker_main(conn: Any, settings: dict[str, Any], warm: bool = True) -> None:
    """Entry point of a worker process: answers commands with ``(result, ok)``."""
    import signal

    # Ctrl-C belongs to the parent, which stops its workers itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # PyBullet's C code prints banners on stdout (the parent's, e.g. a ROS node's); errors
    # travel back through the pipe and stderr stays open.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.close(devnull)
    try:
        from projection_server.simulation.runner import Simulator
        from projection_server.simulation.settings import Settings

        parsed = Settings.from_dict(settings)
        simulator = Simulator()
    except Exception as exc:
        conn.send((ProjectionError('simulation_failed', f'worker start-up: {exc}'), False))
        return
    try:
        from projection_server.workers.warm_up import warm_up

        conn.send(({'warm_up': warm_up(simulator, parsed) if warm else None}, True))
        while True:
            try:
                command, payload = conn.recv()
            except (EOFError, OSError):
                return
            if command == 'close':
                return
            try:
                if command == 'tree':
                    _tree(conn, simulator, payload, parsed)
                    continue
                job, path = payload
                conn.send((simulator.run(job, parsed, Path(path)), True))
            except ProjectionError as exc:
                conn.send((exc, False))
            except Exception as exc:
                conn.send((ProjectionError(
                    'simulation_failed',
                    f'{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=8)}'), False))
    finally:
        simulator.close()


def _tree(conn: Any, simulator: Any, payload: list[tuple[Any, str]], settings: Any) -> None:
    from projection_server.simulation.branching import run_tree

    try:
        complete = run_tree(simulator.client, [(job, Path(path)) for job, path in payload],
                            settings, lambda index, result, ok: conn.send((index, result, ok)))
    except Exception:   # e.g. fork failed: the pool runs what was not reported one by one
        complete = False
    conn.send((None, complete, True))
