"""The ``local`` backend: supervised worker processes on this machine.

Modelled on Gymnasium's ``AsyncVectorEnv``: each worker is a process of an explicit
multiprocessing context (``forkserver`` by default: the parent hosts rclpy and Prolog and
must never be forked) that keeps one warm DIRECT-mode PyBullet client
(:mod:`projection_server.workers.process`), and answers every command with a named message
that carries ``result`` and ``ok`` (:mod:`projection_server.workers.messages`); exceptions
travel back as :class:`ProjectionError`. Every wait in the
parent has a time limit. A worker that crashes or runs over its projection's time limit is
terminated, its projection fails with kind ``worker_crashed`` or ``timeout``, and a new
worker is started at once, ready for the next projection. Workers start with the pool, so
the first projection finds them warm: each has run a throw-away projection
(:mod:`projection_server.workers.warm_up`) before it takes a job. Each projection builds a
fresh world. PyBullet keeps about 0.1 MB per world it has built, even after
``resetSimulation``, so a worker is replaced by a fresh one after ``max_projections``
projections (at once, not when the next projection comes).

The worker translates its projection into a timeline from the samples it has in memory and
sends it back with the bag, so the parent never reads the bag it just had written. Bags go
to a :class:`~projection_server.workers.bag_store.BagStore`.

Workers take queued projections by owner (query) in turn: the next is the oldest of the
owner that has had the fewest taken so far. Queued projections of one family (a program
whose parametrizations share their first steps, from the same set-up,
:mod:`projection_server.simulation.branching`) are taken together, up to a fair share of the
queue per worker, and run as one tree: their shared steps once. A
worker that dies or runs over time in a tree is replaced, and the tree's projections it had
not finished run again one by one, each with its own time limit.
"""

from __future__ import annotations

from collections import deque
import logging
import multiprocessing
from multiprocessing.connection import wait
import os
import shutil
import threading
import time
from typing import Any, NoReturn, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.workers.backend import ProjectionResult
from projection_server.workers.base import BackendBase
from projection_server.workers.messages import (Close, LeafResult, Project, Result, Tree,
                                                TreeEnded)
from projection_server.workers.process import worker_main

_log = logging.getLogger(__name__)  # the node forwards it to /rosout

if TYPE_CHECKING:
    from collections.abc import Mapping

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings
    from projection_server.workers.bag_store import Retention
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

    def __init__(self, bag_dir: str | os.PathLike[str], workers: int = 1,
                 settings: Settings | None = None,
                 retention: Retention | Mapping[str, Any] | None = None,
                 start_method: str = 'forkserver', startup_timeout: float = 60.0,
                 max_projections: int = 200, warm_up: bool = True):
        super().__init__(bag_dir, workers, settings, retention, startup_timeout,
                         max_projections)
        self.warm_up = warm_up
        self._context = multiprocessing.get_context(start_method)
        self._pending: deque[Request] = deque()
        self._ready = threading.Condition(self._lock)
        self._slots = [_Slot(self, i) for i in range(workers)]

    @property
    def workers(self) -> int:
        return len(self._slots)

    @property
    def warm_ups(self) -> list[dict[str, Any] | None]:
        """What each running worker's warm-up took (``seconds``, ``error``); None where a
        worker has not started yet or did not warm up."""
        return [slot.warmed for slot in self._slots]

    @property
    def worker_pids(self) -> list[int | None]:
        """Process ids of the running workers (None where none is running)."""
        return [slot.pid for slot in self._slots]

    def _enqueue(self, request: Request) -> None:
        self._pending.append(request)
        self._ready.notify()
        self._wake_trees()

    def _wake_trees(self) -> None:
        """Have the workers that run trees look for another query's projection to pause
        them for: one may be queued and every worker busy now (with the lock)."""
        for slot in self._slots:
            if len(slot.requests) > 1:
                slot.wake()

    def _take(self) -> list[Request]:
        """The next queued request, with the queued ones of its family up to a fair share
        per worker, all marked running; [] if none is left (with the lock).

        The next is the oldest of the owner (query) that has had the fewest projections
        taken so far: a query that queued a whole grid does not make the next query wait
        for all of it.
        """
        self._pending = deque(r for r in self._pending if not r.future.done())
        first = self._next(list(self._pending), self._pending)
        if first is None:
            return []
        taken = self._family(first)
        self._count(taken)
        self._forget_owners([*self._pending, *taken,
                             *(r for slot in self._slots for r in slot.requests)])
        return taken

    def _take_other(self, owners: set[str | None]) -> Request | None:
        """For a worker that runs a tree of ``owners``' projections: the next queued one of
        other owners, marked running, if every worker is busy; else None (with the lock)."""
        if not all(slot.requests for slot in self._slots):
            return None   # an idle worker takes it
        request = self._next([r for r in self._pending
                              if not r.future.done() and not r.owners & owners],
                             self._pending)
        if request is not None:
            self._count([request])
        return request

    def _family(self, first: Request) -> list[Request]:
        busy = sum(not r.future.done() for slot in self._slots for r in slot.requests)
        taken, self._pending = self._with_family(first, self._pending, busy)
        return taken

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

    def _droppable(self, request: Request) -> bool:
        # A tree runs its projections one after the other: those it has not made yet are
        # dropped like queued ones (see _stop).
        return not request.future.running() or any(
            request in slot.requests and len(slot.requests) > 1 for slot in self._slots)

    def _stop(self, request: Request) -> bool:
        if not request.future.running():
            return False   # queued: its slot skips it
        for slot in self._slots:
            # A tree stops once none of its unfinished projections is wanted any more; the
            # one it was making then fails as cancelled with the others.
            if request in slot.requests and all(
                    r.cancelled for r in slot.requests if not r.future.done()):
                slot.terminate_worker()
        return True

    def close(self) -> None:
        """Stop the workers; queued projections fail with kind ``pool_closed``."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            pending, self._pending = self._pending, deque()
            for request in pending:
                if not request.future.done() and request.future.set_running_or_notify_cancel():
                    request.future.set_exception(
                        ProjectionError(ErrorKind.POOL_CLOSED, 'the projection pool was closed'))
            self._ready.notify_all()
        for slot in self._slots:
            slot.terminate_worker()   # a running projection fails with kind pool_closed
        for slot in self._slots:
            slot.join(10.0)


class _Slot:
    """One worker process and the thread that feeds and supervises it."""

    def __init__(self, pool: WorkerPool, index: int):
        self._pool = pool
        self._process: Any = None
        self._conn: Any = None
        self._projections = 0   # made by the running worker process
        self.requests: list[Request] = []   # the projections it runs (a tree's, or one)
        self.warmed: dict[str, Any] | None = None   # the running worker's warm-up
        # A byte on it wakes a running tree's wait (see WorkerPool._wake_trees).
        self._wake_reader, self._wake_writer = os.pipe()
        os.set_blocking(self._wake_writer, False)
        self._thread = threading.Thread(target=self._loop, name=f'projection-worker-{index}',
                                        daemon=True)
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
        """Wake the wait of the tree this slot runs (with the pool's lock)."""
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
        pool = self._pool
        try:
            try:   # warm before the first projection comes
                self._ensure_worker()
            except ProjectionError:
                pass   # the first projection tries again and reports it
            while True:
                with pool._ready:
                    while not pool._pending and not pool._closed:
                        pool._ready.wait()
                    if pool._closed:
                        return
                    self.requests = requests = pool._take()
                    pool._wake_trees()   # every worker may be busy now
                left = self._run_tree(requests) if len(requests) > 1 else requests
                for request in left:
                    self.requests = [request]
                    self._run(request)
                self.requests = []
                if pool._closed:
                    continue
                if self._projections >= pool.max_projections:
                    self._stop()
                if self._process is None:   # replaced, killed or crashed: start (and warm
                    try:                    # up) its successor while no one waits for it
                        self._ensure_worker()
                    except ProjectionError:
                        pass   # the next projection tries again and reports it
        finally:
            self._stop()
            with pool._lock:
                os.close(self._wake_reader)
                os.close(self._wake_writer)
                self._wake_writer = None

    def _run(self, request: Request) -> None:
        """Run ``request`` (already marked running) and settle its future."""
        pool = self._pool
        if request.future.done():
            return
        try:
            if pool._closed:
                raise ProjectionError(ErrorKind.POOL_CLOSED, 'the projection pool was closed')
            if request.cancelled:
                raise ProjectionError(ErrorKind.CANCELLED, f'projection {request.key[:12]} was cancelled')
            result = self._execute(request)
        except ProjectionError as exc:
            if request.cancelled and exc.kind == ErrorKind.WORKER_CRASHED:
                exc = ProjectionError(
                    ErrorKind.CANCELLED, f'projection {request.key[:12]} was cancelled')
            elif exc.kind in (ErrorKind.WORKER_CRASHED, ErrorKind.TIMEOUT):
                _log.warning('%s; a new worker starts for the next projection', exc)
            with pool._lock:
                pool._requests.fail(request, exc)
        except Exception as exc:  # a bug here must fail the projection, not hang it
            with pool._lock:
                pool._requests.fail(request, ProjectionError(
                    ErrorKind.SIMULATION_FAILED, f'{type(exc).__name__}: {exc}'))
        else:
            request.future.set_result(result)
            self._projections += 1

    def _run_tree(self, requests: list[Request]) -> list[Request]:
        """Run a family's ``requests`` as one tree and settle the futures of those it
        finishes; the others (its worker died or ran over time) are returned, to be run one
        by one. Meanwhile, when every worker is busy, another query's queued projection
        runs in this worker, the tree paused."""
        pool, store = self._pool, self._pool.store
        left = dict(enumerate(requests))
        owners = {o for r in requests for o in r.owners}
        what = f'a tree of {len(requests)} projections from {requests[0].key[:12]}'
        _log.debug('%s', what)
        tmp = store.tmp_dir()
        bags = [tmp / store.name(r.job, r.key) for r in requests]
        other: tuple[Request, Any, float] | None = None   # request, bag, deadline
        try:
            self._ensure_worker()
            try:
                self._conn.send(Tree([(r.job, str(b)) for r, b in zip(requests, bags)]))
            except OSError:   # the worker died while idle
                self._died(what)
            # Each projection of a tree has its limit from the end of the one before.
            deadline = time.monotonic() + max(r.timeout for r in requests)
            ended = False   # the tree has; the other query's projection may still run
            while not ended or other is not None:
                if other is None:
                    with pool._lock:
                        request = pool._take_other(owners)
                    if request is not None:
                        other = (request, tmp / store.name(request.job, request.key),
                                 time.monotonic() + request.timeout)
                        self.requests = [*self.requests, request]
                        self._conn.send(Project(request.job, str(other[1])))
                limit = other[2] if other is not None else deadline
                ready = wait([self._conn, self._process.sentinel, self._wake_reader],
                             timeout=max(0.0, limit - time.monotonic()))
                if self._wake_reader in ready:
                    os.read(self._wake_reader, 4096)
                    if len(ready) == 1:
                        continue   # look for another query's projection (above)
                if not ready:
                    if time.monotonic() < limit:
                        continue
                    self._kill()
                    if other is None:
                        raise ProjectionError(ErrorKind.TIMEOUT, f'{what} ran over time')
                    request, other = other[0], None
                    _log.warning('projection %s took longer than %g s', request.key[:12],
                                 request.timeout)
                    with pool._lock:
                        pool._requests.fail(request, ProjectionError(
                            ErrorKind.TIMEOUT, f'projection {request.key[:12]} took longer than '
                                       f'{request.timeout:g} s'))
                    raise ProjectionError(ErrorKind.WORKER_CRASHED, f'{what} was paused for it')
                try:
                    # A dying worker's pipe reads as EOF, so the pipe is checked first.
                    message = self._conn.recv() if self._conn.poll() else None
                except (EOFError, OSError):
                    message = None
                if message is None:
                    self._died(what)
                if isinstance(message, Result):   # the other query's projection
                    request, bag, _ = other
                    other = None
                    self._settle(request, bag, message.result, message.ok)
                elif isinstance(message, LeafResult):
                    self._settle(left.pop(message.index), bags[message.index], message.result,
                                 message.ok)
                elif isinstance(message, TreeEnded):
                    ended = True
                    continue
                deadline = time.monotonic() + max(
                    (r.timeout for r in left.values()), default=pool.startup_timeout)
        except ProjectionError as exc:
            if exc.kind in (ErrorKind.WORKER_CRASHED, ErrorKind.TIMEOUT) and left:
                _log.warning('%s; a new worker runs its %d unfinished projections one by one',
                             exc, len(left))
        except Exception as exc:  # a bug here must not lose the projections left
            _log.error('%s failed: %s: %s', what, type(exc).__name__, exc)
            self._kill()
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        if other is not None:   # the worker died under it: it runs again, one by one
            left[-1] = other[0]
        return list(left.values())

    def _settle(self, request: Request, bag: Any, result: Any, ok: bool) -> None:
        """Publish ``bag`` and give ``request`` its result, or fail it with ``result``."""
        pool = self._pool
        if ok:
            try:
                final = pool.store.publish(bag)
            except Exception as exc:
                result = ProjectionError(ErrorKind.SIMULATION_FAILED, f'{type(exc).__name__}: {exc}')
            else:
                result['meta']['bag'] = str(final)
                if not request.future.done():
                    request.future.set_result(ProjectionResult(str(final), result))
                self._projections += 1
                return
        with pool._lock:
            pool._requests.fail(request, result)

    def _execute(self, request: Request) -> ProjectionResult:
        self._ensure_worker()
        store = self._pool.store
        tmp = store.tmp_dir()
        # The bag is written under its final name, which is also the name of its storage
        # file inside: identical projections give byte-identical bags.
        bag = tmp / store.name(request.job, request.key)
        what = f'projection {request.key[:12]}'
        try:
            try:
                self._conn.send(Project(request.job, str(bag)))
            except OSError:   # the worker died while idle
                self._died(what)
            timeline, ok = self._receive(request.timeout, what)
            if not ok:
                raise timeline
            final = store.publish(bag)
            timeline['meta']['bag'] = str(final)
            return ProjectionResult(str(final), timeline)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def _receive(self, timeout: float, what: str) -> Any:
        """The worker's answer within ``timeout`` s; on failure the worker is killed."""
        ready = wait([self._conn, self._process.sentinel], timeout=timeout)
        if not ready:
            self._kill()
            raise ProjectionError(ErrorKind.TIMEOUT, f'{what} took longer than {timeout:g} s')
        try:
            # A dying worker's pipe reads as EOF, so the pipe is checked first.
            if self._conn.poll():
                return self._conn.recv()
        except (EOFError, OSError):
            pass
        self._died(what)

    def _died(self, what: str) -> NoReturn:
        self._process.join(1.0)
        code = self._process.exitcode
        self._kill()
        if self._pool._closed:
            raise ProjectionError(ErrorKind.POOL_CLOSED, f'the pool was closed during {what}')
        raise ProjectionError(ErrorKind.WORKER_CRASHED, f'worker died during {what} (exit code {code})')

    def _ensure_worker(self) -> None:
        if self._process is not None and self._process.is_alive():
            return
        self._kill()
        context = self._pool._context
        parent, child = context.Pipe()
        process = context.Process(target=worker_main,
                                  args=(child, self._pool.settings.to_dict(),
                                        self._pool.warm_up),
                                  name='projection-worker', daemon=True)
        process.start()
        child.close()
        self._process, self._conn = process, parent
        self._projections = 0
        message, ok = self._receive(self._pool.startup_timeout, 'worker start-up')
        if not ok:
            self._kill()
            raise message
        self.warmed = message['warm_up']
        if self.warmed is not None and self.warmed['error'] is not None:
            _log.warning('a projection worker could not warm up (its first projection '
                         'pays that): %s', self.warmed['error'])

    def _kill(self) -> None:
        process, conn = self._process, self._conn
        self._process = self._conn = None
        self.warmed = None
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

    def _stop(self) -> None:
        if self._conn is not None and self._process is not None and self._process.is_alive():
            try:
                self._conn.send(Close())
                self._process.join(5.0)
            except OSError:
                pass
        self._kill()

