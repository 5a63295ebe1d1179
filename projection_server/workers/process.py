"""The worker process of both backends: one warm simulator, commands over a pipe.

The ``local`` backend starts it with multiprocessing (:func:`worker_main`); a Ray actor,
whose process has threads of its own and so must not fork, starts it as a command
(:func:`main`), and it forks the trees.

Start-up pays once what every projection would otherwise pay again: imports, the PyBullet
connection, message type registration and asset parsing, and a throw-away projection for
what only a first projection sets up (:mod:`projection_server.workers.warm_up`); the
:class:`~.messages.Ready` message says how long that took. The messages are named
(:mod:`projection_server.workers.messages`). A :class:`~.messages.Project` command is
answered with a :class:`~.messages.Result`; a projection's result is its timeline, made from
the samples the worker has in memory (:mod:`projection_server.workers.run`). A
:class:`~.messages.Tree` command (projections that share their first steps,
:mod:`projection_server.simulation.branching`) is answered with a
:class:`~.messages.LeafResult` for each projection as it ends, then a
:class:`~.messages.TreeEnded`. While a tree runs, the worker also takes
:class:`~.messages.Project` commands (another query's projection): it pauses the tree
(SIGSTOP to its process group), answers with a :class:`~.messages.Result` and continues the
tree. A tree of an engine whose worlds copy runs in the worker's own process, which takes
them after each leaf.
"""

from __future__ import annotations

import os
from pathlib import Path
import time
import traceback
from typing import Any

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.workers import cost
from projection_server.workers.messages import (Close, LeafResult, Project, Ready, Result,
                                                Start, Tree, TreeEnded)

__all__ = ['main', 'worker_main']


def worker_main(conn: Any, settings: dict[str, Any], warm: bool = True) -> None:
    """Entry point of a worker process: sends :class:`Ready`, then answers commands."""
    import signal

    from projection_server.lifetime import die_with_parent

    # Ctrl-C belongs to the parent, which stops its workers itself; a parent that is killed
    # (the node, or the local pool's fork server, which ends with the node) takes them along.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(os.getppid())
    # PyBullet's C code prints banners on stdout (the parent's, e.g. a ROS node's); errors
    # travel back through the pipe and stderr stays open.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.close(devnull)
    try:
        from projection_server.settings import Settings
        from projection_server.simulation.runner import Simulator
        from projection_server.workers import run   # noqa: F401 (the timeline, imported once)

        parsed = Settings.from_dict(settings)
        simulator = Simulator()
    except Exception as exc:
        conn.send(Ready(ProjectionError(ErrorKind.SIMULATION_FAILED, f'worker start-up: {exc}'),
                        False))
        return
    try:
        from projection_server.workers.warm_up import warm_up

        conn.send(Ready({'warm_up': warm_up(simulator, parsed) if warm else None}, True))
        while True:
            try:
                command = conn.recv()
            except (EOFError, OSError):
                return
            if isinstance(command, Close):
                return
            if isinstance(command, Tree):
                _tree(conn, simulator, command.leaves, parsed)
            else:
                _answer(conn, simulator, command, parsed)
    finally:
        simulator.close()


def _answer(conn: Any, simulator: Any, command: Project, settings: Any) -> None:
    """Run ``command`` and send its :class:`Result` (with its cost, if it is logged)."""
    if cost.PATH is None:
        conn.send(_project(simulator, command, settings))
        return
    start, cpu, spent = time.time(), time.process_time(), {}
    conn.send(_project(simulator, command, settings, spent))
    cost.record('projected', command.bag, start=start, end=time.time(),
                cpu=time.process_time() - cpu, **spent)


def _project(simulator: Any, command: Project, settings: Any,
             spent: dict[str, float] | None = None) -> Result:
    from projection_server.workers.run import project

    try:
        return Result(project(simulator, command.job, settings, Path(command.bag), spent),
                      True)
    except ProjectionError as exc:
        return Result(exc, False)
    except Exception as exc:
        return Result(ProjectionError(
            ErrorKind.SIMULATION_FAILED,
            f'{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=8)}'), False)


def _tree(conn: Any, simulator: Any, payload: list[tuple[Any, str]], settings: Any) -> None:
    """Run a tree; answer each leaf as it ends and, meanwhile, :class:`Project` commands
    (of other queries), for which the tree is paused."""
    from multiprocessing.connection import wait
    import pickle
    import signal

    from projection_server.simulation import engines
    from projection_server.simulation.branching import start_tree

    leaves = [(job, Path(path)) for job, path in payload]
    if engines.get(leaves[0][0].settings(settings).physics.engine).copyable:
        _tree_in_process(conn, simulator, leaves, settings)
        return
    reader, writer = os.pipe()

    def ended(index: int) -> Path:   # where a leaf leaves its result
        return leaves[index][1].with_name(leaves[index][1].name + '.result')

    def report(index: int, result: Any, ok: bool) -> None:   # in the leaf's process
        result = _leaf_result(result, ok, leaves[index][1])
        ended(index).write_bytes(pickle.dumps(LeafResult(index, result, ok)))
        os.write(writer, index.to_bytes(4, 'little'))   # one write, under PIPE_BUF: atomic

    start, spent = time.time(), _children_cpu()
    try:
        pid = start_tree(simulator, leaves, settings, report)
    except Exception:   # e.g. fork failed: the pool runs the projections one by one
        os.close(reader)
        os.close(writer)
        conn.send(TreeEnded(False))
        return
    os.close(writer)   # the tree holds it: the pipe ends when the whole tree has
    with os.fdopen(reader, 'rb', buffering=0) as ends:
        pending = b''
        while True:
            ready = wait([conn, ends])
            if conn in ready:
                command = conn.recv()
                if not isinstance(command, Project):   # Close: the tree goes with the worker
                    os.killpg(pid, signal.SIGKILL)
                    os.waitpid(pid, 0)
                    raise SystemExit(0)
                _signal_tree(pid, signal.SIGSTOP)
                try:
                    _answer(conn, simulator, command, settings)
                finally:
                    _signal_tree(pid, signal.SIGCONT)
            if ends in ready:
                chunk = ends.read(4096)
                if not chunk:
                    break
                pending += chunk
                while len(pending) >= 4:
                    index = int.from_bytes(pending[:4], 'little')
                    pending = pending[4:]
                    message = pickle.loads(ended(index).read_bytes())
                    ended(index).unlink()
                    conn.send(message)
    complete = os.waitpid(pid, 0)[1] == 0
    # The tree's CPU: every process of it has been waited for by its parent.
    cost.record('tree', str(leaves[0][1]), start=start, end=time.time(),
                cpu=_children_cpu() - spent, leaves=[os.path.basename(b) for _, b in leaves])
    conn.send(TreeEnded(complete))


def _tree_in_process(conn: Any, simulator: Any, leaves: list[tuple[Any, Path]],
                     settings: Any) -> None:
    """A tree of an engine whose worlds copy, in this process
    (:func:`~projection_server.simulation.branching.run_in_process`): each leaf answered as
    it ends, then the :class:`Project` commands that came meanwhile (another query's
    projection waits for a leaf, not for the tree)."""
    from projection_server.simulation.branching import run_in_process

    def report(index: int, result: Any, ok: bool) -> None:
        conn.send(LeafResult(index, _leaf_result(result, ok, leaves[index][1]), ok))
        while conn.poll():
            command = conn.recv()
            if not isinstance(command, Project):   # Close: the tree goes with the worker
                raise SystemExit(0)
            _answer(conn, simulator, command, settings)

    start, cpu = time.time(), time.process_time()
    complete = run_in_process(simulator, leaves, settings, report)
    cost.record('tree', str(leaves[0][1]), start=start, end=time.time(),
                cpu=time.process_time() - cpu, leaves=[os.path.basename(b) for _, b in leaves])
    conn.send(TreeEnded(complete))


def _leaf_result(result: Any, ok: bool, bag: Path) -> Any:
    """What a tree's leaf answers: a finished projection's timeline, from the records it
    has in memory, or the error as it is; the leaf's cost logged."""
    from projection_server.workers.run import timeline_of

    if not ok:
        return result
    # The leaf's own steps: its clock began at its fork, its copy or the tree's start.
    start = time.process_time()
    cpu = start - result.cpu_from
    timeline = timeline_of(result, bag)
    cost.record('leaf', str(bag), end=time.time(), sim_cpu=cpu,
                timeline_cpu=time.process_time() - start)
    return timeline


def _children_cpu() -> float:
    """CPU seconds of this process's ended and waited-for descendants."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _signal_tree(pid: int, signum: int) -> None:
    """Send ``signum`` to the tree led by ``pid``, unless all of it has ended."""
    try:
        os.killpg(pid, signum)
    except ProcessLookupError:
        pass


def main() -> None:
    """``python -m projection_server.workers.process FD PARENT``: :func:`worker_main` on
    the inherited socket ``FD``, whose first message is a :class:`Start`, in a process that
    dies with its parent, pid ``PARENT``."""
    import sys
    from multiprocessing.connection import Connection

    from projection_server.lifetime import die_with_parent

    fd, parent = int(sys.argv[1]), int(sys.argv[2])
    if not die_with_parent(parent):
        return
    conn = Connection(fd)
    try:
        start = conn.recv()
    except (EOFError, OSError):
        return
    if isinstance(start, Start):
        worker_main(conn, start.settings, start.warm)


if __name__ == '__main__':
    main()
