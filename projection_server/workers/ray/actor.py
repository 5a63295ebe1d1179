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
cluster. Its answers are the worker process's named messages
(:mod:`projection_server.workers.messages`), each carrying ``ok``; a failed projection's
result is its :class:`~projection_server.errors.ProjectionError`, and a finished one's is
``({file name: bytes}, timeline)``. If the worker process dies, so does the actor: Ray
restarts it, and the backend reports the projection it was running as crashed.

While a tree runs, the actor (two threads: ``max_concurrency=2``) takes one ``project``
call beside it, another query's projection: the worker process pauses the tree for it. The
answers of both share the worker's pipe: a :class:`~.messages.Result` is the ``project``
call's, a :class:`~.messages.LeafResult` or :class:`~.messages.TreeEnded` the tree's.
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
from projection_server.workers.messages import (LeafResult, Project, Ready, Result, Start,
                                                Tree, TreeEnded)

if TYPE_CHECKING:
    from collections.abc import Iterator

    from projection_server.simulation.job import Job
    from projection_server.workers.messages import Answer

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
        # Answers read but not yet taken, by whose they are: a call's (Ready, Result) or
        # the tree's (LeafResult, TreeEnded).
        self._inbox: dict[str, deque[Answer]] = {'call': deque(), 'tree': deque()}
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
            self._conn.send(Start(settings, True))
            ready = self._receive('call', exit_on_eof=False)
        except Exception as exc:   # reported by ready(), like a local worker's start-up
            if isinstance(exc, (EOFError, OSError)) and self._process is not None:
                try:
                    exc = f'the worker process exited with code {self._process.wait(5.0)}'
                except subprocess.TimeoutExpired:
                    pass
            self._error = ProjectionError(ErrorKind.SIMULATION_FAILED, f'worker start-up: {exc}')
            return
        if ready.ok:
            self._warm_up = ready.result['warm_up']
        else:
            self._error = ready.result

    def ready(self) -> Ready:
        """Where this actor runs (its ``pid`` and its worker's ``worker_pid``) and which
        code it has, or why it could not start."""
        if self._error is not None:
            return Ready(self._error, False)
        import ray

        return Ready({'pid': os.getpid(), 'worker_pid': self._process.pid,
                      'node': ray.get_runtime_context().get_node_id(),
                      'code_version': self._code, 'warm_up': self._warm_up}, True)

    def project(self, job: Job, name: str) -> Result:
        """Run ``job`` into a bag called ``name``: ``Result(({file: bytes}, timeline), True)``
        or ``Result(error, False)``."""
        if self._error is not None:
            return Result(self._error, False)
        tmp = private_tmp_dir('projection-ray-')
        try:
            bag = tmp / name
            self._send(Project(job, str(bag)))
            result = self._receive('call')
            return Result((_files(bag), result.result), True) if result.ok else result
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def tree(self, leaves: list[tuple[Job, str]]) -> Iterator[LeafResult | TreeEnded]:
        """Run the projections ``leaves`` (a job and a bag name each; one family) as a tree
        (:mod:`projection_server.simulation.branching`); yield a :class:`LeafResult` for
        each as it ends, its result as :meth:`project`'s, then a :class:`TreeEnded`."""
        if self._error is not None:
            yield TreeEnded(False)   # the backend runs them one by one: each says why
            return
        tmp = private_tmp_dir('projection-ray-')
        try:
            bags = [tmp / name for _, name in leaves]
            self._send(Tree([(job, str(bag)) for (job, _), bag in zip(leaves, bags)]))
            while True:
                message = self._receive('tree')
                if isinstance(message, TreeEnded):
                    yield message
                    return
                if message.ok:
                    message = message._replace(
                        result=(_files(bags[message.index]), message.result))
                    shutil.rmtree(bags[message.index], ignore_errors=True)
                yield message
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def _send(self, command: Project | Tree) -> None:
        with self._sending:
            self._conn.send(command)

    def _receive(self, whose: str, exit_on_eof: bool = True) -> Answer:
        """The next answer from the worker process to ``whose`` (``'call'`` or ``'tree'``);
        one thread reads at a time and leaves the other's answers in the inbox. If the
        worker process has died, the actor exits (EOFError instead without
        ``exit_on_eof``)."""
        inbox = self._inbox[whose]
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
                tree = isinstance(answer, (LeafResult, TreeEnded))
                self._inbox['tree' if tree else 'call'].append(answer)
                self._answers.notify_all()


def _files(bag: Path) -> dict[str, bytes]:
    return {entry.name: entry.read_bytes() for entry in sorted(bag.iterdir())}
