"""The Ray actor of the ``ray`` backend: a warm simulator in a worker process of its own.

ROS-free on purpose (no rclpy: it may run on any machine of a cluster). A Ray worker process
has threads of its own, so it must not fork: the actor starts the worker process of the
``local`` backend (:mod:`projection_server.workers.process`) as a command, once, and that
process, single-threaded, runs the projections and forks the trees of projections that
share their first steps. It pays imports, the PyBullet connection, message type
registration and a throw-away projection (:mod:`projection_server.workers.warm_up`) once,
runs each projection in a fresh world, makes its timeline from the samples in memory and
dies with the actor. Bags are written into a private temporary directory on the actor's
machine (one left by an actor killed meanwhile is deleted by the next projection there) and
sent back as bytes, so the node's bag directory needs no file system shared with the
cluster. Every answer carries ``ok``; a failed projection's result is its
:class:`~projection_server.errors.ProjectionError`. If the worker process dies,
so does the actor: Ray restarts it, and the backend reports the projection it was running
as crashed.

While a tree runs, the actor (two threads: ``max_concurrency=2``) takes one ``project``
call beside it, another query's projection: the worker process pauses the tree for it. The
answers of both share the worker's pipe and are told apart by their length.
"""

from __future__ import annotations

from collections import deque
import os
from pathlib import Path
import shutil
import threading
from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.workers.bag_store import private_tmp_dir

if TYPE_CHECKING:
    from collections.abc import Iterator

    from projection_server.simulation.job import Job

__all__ = ['ProjectionActor']


class ProjectionActor:
    """A warm PyBullet client in a worker process that runs projections and trees; made
    remote by the backend."""

    def __init__(self, settings: dict[str, Any]):
        import socket
        import subprocess
        import sys
        from multiprocessing.connection import Connection

        self._error: ProjectionError | None = None
        self._warm_up: dict[str, Any] | None = None
        self._process: Any = None
        self._sending = threading.Lock()
        self._answers = threading.Condition()
        # Answers read but not yet taken, by length: (result, ok) of a projection,
        # (index, result, ok) of a tree's.
        self._inbox: dict[int, deque[tuple[Any, ...]]] = {2: deque(), 3: deque()}
        self._reading = False
        try:
            from projection_server.simulation.job import code_version

            self._code = code_version()
            ours, theirs = socket.socketpair()
            # Exec, not fork: PyBullet's banners go to /dev/null, errors come back as results.
            self._process = subprocess.Popen(
                [sys.executable, '-m', 'projection_server.workers.process',
                 str(theirs.fileno()), str(os.getpid())],
                pass_fds=[theirs.fileno()], stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL)
            theirs.close()
            self._conn = Connection(ours.detach())
            self._conn.send((settings, True))
            message, ok = self._receive(2, exit_on_eof=False)
        except Exception as exc:   # reported by ready(), like a local worker's start-up
            if isinstance(exc, (EOFError, OSError)) and self._process is not None:
                try:
                    exc = f'the worker process exited with code {self._process.wait(5.0)}'
                except subprocess.TimeoutExpired:
                    pass
            self._error = ProjectionError(ErrorKind.SIMULATION_FAILED, f'worker start-up: {exc}')
            return
        if ok:
            self._warm_up = message['warm_up']
        else:
            self._error = message

    def ready(self) -> tuple[Any, bool]:
        """Where this actor runs (its ``pid`` and its worker's ``worker_pid``) and which
        code it has, or why it could not start."""
        if self._error is not None:
            return self._error, False
        import ray

        return {'pid': os.getpid(), 'worker_pid': self._process.pid,
                'node': ray.get_runtime_context().get_node_id(),
                'code_version': self._code, 'warm_up': self._warm_up}, True

    def project(self, job: Job, name: str) -> tuple[Any, bool]:
        """Run ``job`` into a bag called ``name``: ``(({file: bytes}, timeline), True)``."""
        if self._error is not None:
            return self._error, False
        tmp = private_tmp_dir('projection-ray-')
        try:
            bag = tmp / name
            self._send(('project', (job, str(bag))))
            timeline, ok = self._receive(2)
            return ((_files(bag), timeline) if ok else timeline), ok
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def tree(self, leaves: list[tuple[Job, str]]) -> Iterator[tuple[Any, Any, bool]]:
        """Run the projections ``leaves`` (a job and a bag name each; one family) as a tree
        (:mod:`projection_server.simulation.branching`); yield ``(index, result, ok)`` for
        each as it ends, as :meth:`project` answers, then ``(None, complete, True)``:
        ``complete`` is False if a process of the tree crashed before it reported."""
        if self._error is not None:
            yield None, False, True   # the backend runs them one by one: each says why
            return
        tmp = private_tmp_dir('projection-ray-')
        try:
            bags = [tmp / name for _, name in leaves]
            self._send(('tree', [(job, str(bag)) for (job, _), bag in zip(leaves, bags)]))
            while True:
                index, result, ok = self._receive(3)
                if index is None:
                    yield None, result, True
                    return
                if ok:
                    result = (_files(bags[index]), result)
                    shutil.rmtree(bags[index], ignore_errors=True)
                yield index, result, ok
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def _send(self, command: tuple[str, Any]) -> None:
        with self._sending:
            self._conn.send(command)

    def _receive(self, size: int, exit_on_eof: bool = True) -> tuple[Any, ...]:
        """The next answer of length ``size`` from the worker process; one thread reads at
        a time and leaves the other's answers in the inbox. If the worker process has died,
        the actor exits (EOFError instead without ``exit_on_eof``)."""
        inbox = self._inbox[size]
        while True:
            with self._answers:
                while not inbox and self._reading:
                    self._answers.wait()
                if inbox:
                    return inbox.popleft()
                self._reading = True
            try:
                answer = self._conn.recv()
            except (EOFError, OSError):
                if not exit_on_eof:
                    raise EOFError from None
                # The worker process died (a crash of the simulation): the actor goes with
                # it, and Ray restarts both.
                os._exit(1)
            with self._answers:
                self._reading = False
                self._inbox[len(answer)].append(answer)
                self._answers.notify_all()


def _files(bag: Path) -> dict[str, bytes]:
    return {entry.name: entry.read_bytes() for entry in sorted(bag.iterdir())}
