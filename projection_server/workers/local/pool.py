"""The ``local`` backend: supervised worker processes on this machine.

Modelled on Gymnasium's ``AsyncVectorEnv``: each worker is a process of an explicit
multiprocessing context (``forkserver`` by default: the parent hosts rclpy and Prolog and
must never be forked) that keeps one warm DIRECT-mode PyBullet client
(:mod:`projection_server.workers.process`) and answers every command with a named message
that carries ``result`` and ``ok`` (:mod:`projection_server.workers.messages`); exceptions
travel back as :class:`ProjectionError`. Every wait in the parent has a time limit. Workers
start with the pool, so the first projection finds them warm: each has run a throw-away
projection (:mod:`projection_server.workers.warm_up`) before it takes a job. Each
projection builds a fresh world.

What each worker does next is decided by :class:`~projection_server.workers.base.BackendBase`
(fair turns, trees of a family's projections, pausing a tree for another query's projection,
time limits, what a crash or a cancel fails, replacement after ``max_projections``); this
module only carries it out. A worker is a slot: a process, its pipe and a thread that feeds
and supervises it. The thread waits until its :class:`~projection_server.workers.base.Worker`
has work, sends it, and waits on the pipe, the process's sentinel and a wake-up pipe (a byte
on it when its tree is to be paused, or the worker stopped) until the work's time limit; it
reports each answer, the time limit and the process's death to the policy, kills a worker
that is to stop (SIGTERM, then SIGKILL), and starts a new one when the policy says so.

The worker translates its projection into a timeline from the samples it has in memory and
sends it back with the bag, so the parent never reads the bag it just had written. Bags go
to a :class:`~projection_server.workers.bag_store.BagStore`.
"""

from __future__ import annotations

import logging
import multiprocessing
from multiprocessing.connection import wait
import os
import shutil
import threading
import time
from typing import Any, ClassVar, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.workers import cost
from projection_server.workers.backend import ProjectionResult
from projection_server.workers.base import BackendBase, BUSY, WorkerState
from projection_server.workers.messages import (Close, LeafResult, Project, Ready, Result,
                                                Tree, TreeEnded)
from projection_server.workers.process import worker_main

_log = logging.getLogger(__name__)  # the node forwards it to /rosout

if TYPE_CHECKING:
    from collections.abc import Mapping
    from pathlib import Path

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings
    from projection_server.workers.bag_store import Retention
    from projection_server.workers.base import Worker
    from projection_server.workers.messages import Answer, Command
    from projection_server.workers.requests import Request

__all__ = ['WorkerPool']

_POLL = 1.0   # s between liveness checks while waiting for a result


class WorkerPool(BackendBase):
    """``workers`` supervised projection processes writing bags into ``bag_dir``.

    ``submit`` queues a projection and returns a :class:`~concurrent.futures.Future` of its
    :class:`ProjectionResult`; identical projections (same key) share one future and one
    bag. ``run`` is submit and wait. Close the pool (or use it as a context manager) to
    stop the workers. Implements :class:`~projection_server.workers.backend.WorkerBackend`.
    """

    _log: ClassVar[logging.Logger] = _log

    def __init__(self, bag_dir: str | os.PathLike[str], workers: int = 1,
                 settings: Settings | None = None,
                 retention: Retention | Mapping[str, Any] | None = None,
                 start_method: str = 'forkserver', startup_timeout: float = 60.0,
                 max_projections: int = 200, warm_up: bool = True):
        super().__init__(bag_dir, workers, settings, retention, startup_timeout,
                         max_projections)
        self.warm_up = warm_up
        self._context = multiprocessing.get_context(start_method)
        self._work = threading.Condition(self._lock)   # a slot's worker has work, or closed
        self._slots = [_Slot(self, worker) for worker in self._roster]

    @property
    def warm_ups(self) -> list[dict[str, Any] | None]:
        """What each running worker's warm-up took (``seconds``, ``error``); None where a
        worker has not started yet or did not warm up."""
        return [slot.warmed for slot in self._slots]

    @property
    def worker_pids(self) -> list[int | None]:
        """Process ids of the running workers (None where none is running)."""
        return [slot.pid for slot in self._slots]

    def run(self, job: Job, timeout: float) -> str:
        """Run ``job`` (or find its bag) and return the bag's path.

        Raises:
            ProjectionError: of the projection, or kind ``pool_closed``.
        """
        future = self.submit(job, timeout)
        while True:
            try:
                return future.result(timeout=_POLL).bag
            except TimeoutError:
                if not any(slot.alive for slot in self._slots):
                    raise ProjectionError(ErrorKind.POOL_CLOSED, 'no worker supervisor is running')

    def close(self) -> None:
        """Stop the workers; queued projections fail with kind ``pool_closed``."""
        closed = ProjectionError(ErrorKind.POOL_CLOSED, 'the projection pool was closed')
        with self._lock:
            if self._closed:
                return
            self._closed = True
            while self._queue:
                self._requests.fail(self._queue.popleft(), closed)
            self._work.notify_all()
        for slot in self._slots:
            slot.terminate_worker()   # a running projection fails with kind pool_closed
        for slot in self._slots:
            slot.join(10.0)
        with self._lock:
            self._fail_all(closed)

    # -- the transport --------------------------------------------------------------------
    def _send(self, worker: Worker) -> None:
        self._work.notify_all()

    def _send_other(self, worker: Worker) -> None:
        self._slots[worker.index].wake()

    def _halt(self, worker: Worker) -> None:
        slot = self._slots[worker.index]
        slot.terminate_worker()
        slot.wake()

    def _restart(self, worker: Worker) -> None:
        self._work.notify_all()


def _spare_ahead(pool: WorkerPool) -> int:
    """How many projections before its replacement is due a worker's successor starts: a
    tenth of its share, time for a start-up and warm-up of a few seconds."""
    return max(1, pool.max_projections // 10)


def _close_process(process: Any, conn: Any) -> None:
    """Close ``conn`` and end ``process`` (SIGTERM, then SIGKILL)."""
    if conn is not None:
        conn.close()
    if process is not None:
        if process.is_alive():
            process.terminate()
            process.join(2.0)
        if process.is_alive():
            process.kill()
            process.join(2.0)
        if not process.is_alive():
            process.close()


class _WorkerDied(Exception):
    """The worker process ended (``cause`` says how)."""

    def __init__(self, cause: str):
        super().__init__(cause)
        self.cause = cause


class _Slot:
    """One worker process, its pipe, and the thread that feeds and supervises it."""

    def __init__(self, pool: WorkerPool, worker: Worker):
        self._pool = pool
        self.worker = worker
        self._process: Any = None
        self._conn: Any = None
        # The process that is to replace this one (with its pipe), started while the one it
        # replaces still works: its start-up and warm-up (seconds) then cost the queries no
        # wait when the replacement is due.
        self._spare: tuple[Any, Any] | None = None
        self.warmed: dict[str, Any] | None = None   # the running worker's warm-up
        # A byte on it wakes the slot's wait (its tree is to be paused, or it is stopped).
        self._wake_reader, self._wake_writer = os.pipe()
        os.set_blocking(self._wake_writer, False)
        self._thread = threading.Thread(target=self._loop,
                                        name=f'projection-worker-{worker.index}', daemon=True)
        self._thread.start()

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    @property
    def pid(self) -> int | None:
        process = self._process
        return process.pid if process is not None and process.is_alive() else None

    def join(self, timeout: float) -> None:
        self._thread.join(timeout)

    def wake(self) -> None:
        """Wake the slot's wait (with the pool's lock)."""
        if self._wake_writer is not None:
            try:
                os.write(self._wake_writer, b'\0')
            except BlockingIOError:   # full: it wakes anyway
                pass

    def terminate_worker(self) -> None:
        """Ask the running worker to stop (SIGTERM); its supervisor thread cleans up."""
        process = self._process
        if process is not None:
            try:
                process.terminate()
            except (ValueError, AttributeError):   # closed by the supervisor meanwhile
                pass

    def _loop(self) -> None:
        pool, worker = self._pool, self.worker
        try:
            while True:
                with pool._lock:
                    while (worker.state in (WorkerState.IDLE, WorkerState.FAILED)
                           and not pool._closed):
                        pool._work.wait()
                    if pool._closed:
                        return
                    state = worker.state
                if state is WorkerState.STARTING:   # warm before a projection comes
                    self._start()
                elif state is WorkerState.STOPPING:   # stopped before its work was sent
                    self._end('stopped')
                else:
                    self._serve()
        finally:
            self._stop()
            self._drop_spare()
            with pool._lock:
                os.close(self._wake_reader)
                os.close(self._wake_writer)
                self._wake_writer = None

    def _start(self) -> None:
        """Start a fresh worker process in place of the one before, if any."""
        pool = self._pool
        self._stop()
        try:
            self._ensure_worker()
        except ProjectionError as exc:
            with pool._lock:
                pool._start_failed(self.worker, exc)
            return
        with pool._lock:
            pool._started(self.worker)

    def _serve(self) -> None:
        """Run what the worker has taken, a projection or a tree, until it is done: send it,
        then report each answer (and send the projection its tree is paused for)."""
        pool, worker, store = self._pool, self.worker, self._pool.store
        with pool._lock:
            request, leaves, taken = worker.request, dict(worker.leaves), worker.taken
        tmps: list[Path] = []   # the tree's temporary directory, and each projection's
        projecting: tuple[Request, Path] | None = None   # a Project sent, not answered
        if request is not None:
            projecting = self._projecting(request, tmps)
            first: Command = Project(request.job, str(projecting[1]))
            what = f'projection {request.key[:12]}'
        else:
            tmps.append(store.tmp_dir())
            bags = {i: tmps[0] / store.name(r.job, r.key) for i, r in leaves.items()}
            first = Tree([(r.job, str(bags[i])) for i, r in leaves.items()])
            what = f'a tree of {len(leaves)} projections from {leaves[0].key[:12]}'
        try:
            try:
                self._ensure_worker()   # it may have died while idle
            except ProjectionError as exc:
                with pool._lock:
                    pool._start_failed(worker, exc)
                return
            if not self._command(first):
                self._end(self._exit())
                return
            with pool._lock:
                pool._clock(worker)   # its time limit counts from here
            while True:
                command = None
                with pool._lock:
                    state, deadline = worker.state, worker.deadline
                    moved_on = worker.taken != taken
                    if state is WorkerState.TREE_PAUSED and projecting is None:
                        projecting = self._projecting(worker.other, tmps)
                        command = Project(worker.other.job, str(projecting[1]))
                if state is WorkerState.STOPPING:
                    self._end('stopped')
                    return
                if state not in BUSY or moved_on:
                    return   # done (and maybe given its next work already)
                if command is not None and not self._command(command):
                    self._end(self._exit())
                    return
                try:
                    message = self._receive(max(0.0, deadline - time.monotonic()), what)
                except _WorkerDied as died:
                    self._end(died.cause)
                    return
                if message is None:   # woken, or over time
                    with pool._lock:
                        pool._overdue(worker, time.monotonic())
                elif isinstance(message, Result):
                    answered, bag = projecting
                    projecting = None
                    _log.debug('projection answered by its worker: %s', bag.name)
                    result = self._published(bag, message)
                    shutil.rmtree(bag.parent, ignore_errors=True)   # before it is answered
                    with pool._lock:
                        pool._answered(worker, answered, result)
                        due = worker.projections >= pool.max_projections - _spare_ahead(pool)
                    cost.record('answered', bag.name, t=time.time())
                    if due:
                        self._start_spare()
                elif isinstance(message, LeafResult):
                    result = self._published(bags[message.index], message)
                    with pool._lock:
                        pool._leaf_answered(worker, message.index, result)
                        due = worker.projections >= pool.max_projections - _spare_ahead(pool)
                    cost.record('answered', bags[message.index].name, t=time.time())
                    if due:
                        self._start_spare()
                elif isinstance(message, TreeEnded):
                    with pool._lock:
                        pool._tree_ended(worker)
        except Exception as exc:  # a bug here must fail the projections, not hang them
            _log.error('%s failed: %s: %s', what, type(exc).__name__, exc)
            self._end(f'{type(exc).__name__}: {exc}')
        finally:
            for tmp in tmps:
                shutil.rmtree(tmp, ignore_errors=True)

    def _projecting(self, request: Request, tmps: list[Path]) -> tuple[Request, Path]:
        """``request`` and the path of its bag, in a temporary directory of its own (added
        to ``tmps``). A bag is written under its final name, which is also the name of its
        storage file inside: identical projections give byte-identical bags."""
        store = self._pool.store
        tmps.append(store.tmp_dir())
        return request, tmps[-1] / store.name(request.job, request.key)

    def _published(self, bag: Path, message: Result | LeafResult
                   ) -> ProjectionResult | ProjectionError:
        """Publish ``bag`` with the timeline of ``message``; or its error."""
        if not message.ok:
            return message.result
        try:
            final = self._pool.store.publish(bag)
        except Exception as exc:
            return ProjectionError(ErrorKind.SIMULATION_FAILED, f'{type(exc).__name__}: {exc}')
        timeline = message.result
        timeline['meta']['bag'] = str(final)
        return ProjectionResult(str(final), timeline)

    def _command(self, command: Command) -> bool:
        """Send ``command``; False if the worker has died."""
        try:
            self._conn.send(command)
        except OSError:
            return False
        if cost.PATH is not None:
            for bag in ([command.bag] if isinstance(command, Project) else
                        [bag for _, bag in command.leaves] if isinstance(command, Tree) else []):
                cost.record('sent', bag, t=time.time())
        if isinstance(command, Project):   # when a worker was given work, for benchmarks
            _log.debug('projection sent to its worker: %s', os.path.basename(command.bag))
        return True

    def _receive(self, timeout: float, what: str) -> Answer | None:
        """The worker's next message within ``timeout`` s; None if none came (or the slot
        was woken).

        Raises:
            _WorkerDied: with its exit code.
        """
        ready = wait([self._conn, self._process.sentinel, self._wake_reader], timeout=timeout)
        if self._wake_reader in ready:
            os.read(self._wake_reader, 4096)
        try:
            # A dying worker's pipe reads as EOF, so the pipe is checked first.
            if self._conn.poll():
                return self._conn.recv()
        except (EOFError, OSError):
            raise _WorkerDied(self._exit()) from None
        if self._process.sentinel in ready:
            raise _WorkerDied(self._exit())
        return None

    def _exit(self) -> str:
        """How the worker process ended."""
        self._process.join(1.0)
        return f'exit code {self._process.exitcode}'

    def _end(self, cause: str) -> None:
        """The worker process ends under its work: kill what is left of it, report it."""
        self._kill()
        with self._pool._lock:
            self._pool._lost(self.worker, cause)

    def _ensure_worker(self) -> None:
        if self._process is not None and self._process.is_alive():
            return
        self._kill()
        pool = self._pool
        spare, self._spare = self._spare, None
        if spare is not None and spare[0].is_alive():
            process, parent = spare   # started ahead: it may be warm already
        else:
            if spare is not None:
                _close_process(*spare)
            process, parent = self._new_process()
        self._process, self._conn = process, parent
        what = 'worker start-up'
        deadline = time.monotonic() + pool.startup_timeout
        try:
            message = None
            while message is None and time.monotonic() < deadline:
                message = self._receive(max(0.0, deadline - time.monotonic()), what)
        except _WorkerDied as died:
            message = Ready(ProjectionError(ErrorKind.WORKER_CRASHED,
                                            f'worker died during {what} ({died.cause})'), False)
        if message is None:
            message = Ready(ProjectionError(
                ErrorKind.TIMEOUT, f'{what} took longer than {pool.startup_timeout:g} s'), False)
        if not isinstance(message, Ready) or not message.ok:
            self._kill()
            if pool._closed:
                raise ProjectionError(ErrorKind.POOL_CLOSED, f'the pool was closed during {what}')
            raise message.result
        self.warmed = message.result['warm_up']
        if self.warmed is not None and self.warmed['error'] is not None:
            _log.warning('a projection worker could not warm up (its first projection '
                         'pays that): %s', self.warmed['error'])

    def _new_process(self) -> tuple[Any, Any]:
        """A worker process started (not waited for) and the parent's end of its pipe."""
        pool = self._pool
        parent, child = pool._context.Pipe()
        process = pool._context.Process(target=worker_main,
                                        args=(child, pool.settings.to_dict(), pool.warm_up),
                                        name='projection-worker', daemon=True)
        process.start()
        child.close()
        return process, parent

    def _start_spare(self) -> None:
        """Start the process that is to replace this slot's worker, unless it runs."""
        if self._spare is None and not self._pool._closed:
            self._spare = self._new_process()

    def _drop_spare(self) -> None:
        spare, self._spare = self._spare, None
        if spare is not None:
            _close_process(*spare)

    def _kill(self) -> None:
        process, conn = self._process, self._conn
        self._process = self._conn = None
        self.warmed = None
        if process is not None or conn is not None:
            _close_process(process, conn)

    def _stop(self) -> None:
        if self._conn is not None and self._process is not None and self._process.is_alive():
            try:
                self._conn.send(Close())
                self._process.join(5.0)
            except OSError:
                pass
        self._kill()
