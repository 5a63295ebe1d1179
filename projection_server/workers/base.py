"""What every worker backend shares: the bag store and settings, the requests by job key,
and the scheduling policy, all under one lock.

The policy decides, for both backends alike, from one record per worker (:class:`Worker`)
whose state is named (:class:`WorkerState`):

* **Fair turns.** The next queued projection is the oldest of the owner (query) that has
  had the fewest taken so far, so a query that queued a grid does not make the next query
  wait for all of it. Queued projections of its family (a program whose parametrizations
  share their first steps, :mod:`projection_server.simulation.branching`) are taken with
  it, up to a fair share per worker of what is left to do, and run as one tree.
* **Pausing a tree.** While no worker is idle, a worker whose tree has projections left
  pauses it for a queued projection of owners other than those of its unfinished ones
  (``TREE_PAUSED``); a starting worker counts as busy.
* **Time limits.** A projection's limit counts from when its worker takes it; a tree's
  restarts when one of its projections ends, and with the longest limit of those left; the
  projection a tree is paused for has its own, and the pause does not count against the
  tree.
* **Failures.** A worker that dies or runs over time fails its projection (kind
  ``worker_crashed``, ``timeout``, ``cancelled`` or ``pool_closed``, by why it was
  stopped) and starts again; a tree's unfinished projections are queued again, first,
  each to run on its own with its own limit, since it is not known which one did it. A
  worker that could not start fails the next projection it is given with why, and starts
  again.
* **Cancelling.** A queued projection is dropped; a running one stops its worker; a tree
  stops once none of its unfinished projections is wanted (a paused one, once the
  projection it is paused for has ended); that projection finishes (stopping it would stop
  the tree). Dropping an owner's projections (``cancel(owner, running=False)``) takes the
  queued ones and those a tree with more than one left has not made.
* **Replacement.** PyBullet keeps a little memory per world it has built, so a worker is
  replaced by a fresh one after ``max_projections`` projections, as soon as it is idle.

A backend only transports: it says how a worker is given its work (:meth:`_send`), the
projection its tree is paused for (:meth:`_send_other`), how a worker is stopped
(:meth:`_halt`) and replaced (:meth:`_restart`), and it tells the policy what happened
(:meth:`_started`, :meth:`_start_failed`, :meth:`_answered`, :meth:`_leaf_answered`,
:meth:`_tree_ended`, :meth:`_lost`, :meth:`_overdue`), with the lock held.

    =============  =====================  ===================================================
    state          runs                   next
    =============  =====================  ===================================================
    STARTING                              IDLE (started), FAILED (could not)
    FAILED                                STARTING (a projection given to it fails with why)
    IDLE                                  RUNNING or RUNNING_TREE (it takes work)
    RUNNING        ``request``            IDLE when answered (STARTING: replaced)
    RUNNING_TREE   ``leaves`` left        TREE_PAUSED; IDLE when it ends (STARTING: replaced)
    TREE_PAUSED    ``leaves``, ``other``  RUNNING_TREE when ``other`` ends; RUNNING
                                          (``other``) if the tree ends first
    (those three)                         STOPPING (a time limit, a cancel); STARTING (died)
    STOPPING       what it ran            STARTING once its end is seen
    =============  =====================  ===================================================
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections import deque
from dataclasses import dataclass, field
import enum
import logging
import math
import threading
import time
from typing import Any, ClassVar, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.settings import load_settings
from projection_server.workers import cost
from projection_server.workers.backend import ProjectionResult
from projection_server.workers.bag_store import BagStore
from projection_server.workers.requests import check_timeout, Requests

if TYPE_CHECKING:
    from collections.abc import Iterable, Mapping, Sequence
    from concurrent.futures import Future
    import os

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings
    from projection_server.workers.bag_store import Retention
    from projection_server.workers.requests import Request

__all__ = ['BUSY', 'BackendBase', 'Worker', 'WorkerState']


class WorkerState(enum.Enum):
    """What a worker does."""

    STARTING = 'starting'           # its process (or actor) starts and warms up
    FAILED = 'failed'               # it could not start: the next projection fails with why
    IDLE = 'idle'
    RUNNING = 'running'             # one projection
    RUNNING_TREE = 'running_tree'   # a family's projections as one tree
    TREE_PAUSED = 'tree_paused'     # its tree, paused for another query's projection
    STOPPING = 'stopping'           # stopped (a time limit, a cancel) until its end is seen


# The states in which a worker runs projections under a time limit.
BUSY = (WorkerState.RUNNING, WorkerState.RUNNING_TREE, WorkerState.TREE_PAUSED)


@dataclass(eq=False)
class Worker:
    """One worker's state and what it runs: ``request`` (``RUNNING``), a tree's unfinished
    projections ``leaves`` by index (``RUNNING_TREE``; also ``other``, the projection its
    tree is paused for, in ``TREE_PAUSED``), until ``deadline``. A ``STOPPING`` worker keeps
    them until its end is seen; ``overdue`` is the one that ran over time, if that is why.
    ``taken`` counts the work it has taken, to tell one piece of work from the next.
    """

    index: int
    state: WorkerState = WorkerState.STARTING
    request: Request | None = None
    leaves: dict[int, Request] = field(default_factory=dict)
    other: Request | None = None
    deadline: float = math.inf
    overdue: Request | None = None
    projections: int = 0   # answered since it started
    taken: int = 0
    error: ProjectionError | None = None   # FAILED: why

    def running(self) -> list[Request]:
        """The unfinished projections it runs."""
        running = [self.request, *self.leaves.values(), self.other]
        return [r for r in running if r is not None and not r.future.done()]

    def pausable_owners(self) -> set[str | None] | None:
        """The owners of the projections its tree has not finished, if it could pause the
        tree for another query's projection; None if it runs no tree or runs one beside
        it already. A tree whose projections have all ended but whose end has not come
        has none to pause for: a projection started beside it would only keep the worker
        from its next tree (and split the next family into single projections)."""
        if self.state is not WorkerState.RUNNING_TREE or not self.leaves:
            return None
        return {o for r in self.leaves.values() for o in r.owners}


class BackendBase(ABC):
    """``workers`` workers writing bags into ``bag_dir``; see
    :class:`~projection_server.workers.backend.WorkerBackend`. A subclass makes
    ``self._roster``, one :class:`Worker` per worker, and implements the transport."""

    _log: ClassVar[logging.Logger] = logging.getLogger(__name__)

    def __init__(self, bag_dir: str | os.PathLike[str], workers: int,
                 settings: Settings | None, retention: Retention | Mapping[str, Any] | None,
                 startup_timeout: float, max_projections: int):
        if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
            raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                                  f'workers must be >= 1, got {workers!r}')
        self.store = BagStore(bag_dir, retention)
        self.bag_dir = self.store.bag_dir
        self.settings = settings if settings is not None else load_settings()
        self.startup_timeout = startup_timeout
        self.max_projections = max_projections
        self._lock = threading.Lock()
        self._requests = Requests(self.store)
        self._queue: deque[Request] = deque()
        self._roster = [Worker(i) for i in range(workers)]
        self._served: dict[str | None, int] = {}   # projections taken, by owner
        self._closed = False

    def __enter__(self) -> BackendBase:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def workers(self) -> int:
        """How many projections run at once (the useful prefetch depth)."""
        return len(self._roster)

    @property
    def retention(self) -> Retention:
        return self.store.retention

    def submit(self, job: Job, timeout: float,
               owner: str | None = None) -> Future[ProjectionResult]:
        """Queue ``job``; its simulation may take ``timeout`` seconds of wall-clock time,
        counted from when a worker takes it. Identical jobs share one future."""
        return self.submit_all([job], timeout, owner)[0]

    def submit_all(self, jobs: Sequence[Job], timeout: float,
                   owner: str | None = None) -> list[Future[ProjectionResult]]:
        """:meth:`submit` each of ``jobs``, queued at once (so that a worker can take the
        projections of one family together)."""
        check_timeout(timeout)
        for job in jobs:   # a program its engine cannot run is refused before it is queued
            job.check_engine(self.settings)
        keys = [job.key(self.settings) for job in jobs]
        futures = []
        with self._lock:
            if self._closed:
                raise ProjectionError(ErrorKind.POOL_CLOSED, 'the projection backend is closed')
            for job, key in zip(jobs, keys):
                request, new = self._requests.add(job, key, timeout, owner)
                if new:
                    request.family = job.family(self.settings)
                    self._queue.append(request)
                    if cost.PATH is not None:
                        cost.record('queued', self.store.name(job, key), t=time.time())
                futures.append(request.future)
            self._schedule()
        return futures

    def cancel(self, owner: str, running: bool = True) -> int:
        """Cancel the unfinished projections that only ``owner`` asked for; how many.

        A queued one is dropped, a running one stops its worker (which is replaced); their
        futures fail with kind ``cancelled``. With ``running`` False only the queued ones
        are dropped, and the projections of a tree that it has not made yet: the running
        ones finish and their bags are kept (a tree stops once none of those it has not
        made is wanted).
        """
        cancelled = 0
        with self._lock:
            for request in self._requests.only_for(owner):
                if not running and not self._droppable(request):
                    continue
                request.cancelled = True
                cancelled += 1
                if not self._stop(request):   # queued: fails now; else when its worker ends
                    self._requests.fail(request, ProjectionError(
                        ErrorKind.CANCELLED, f'projection {request.key[:12]} was cancelled'))
        return cancelled

    @abstractmethod
    def close(self) -> None:
        """Stop the workers; unfinished projections fail with kind ``pool_closed``."""

    # -- the transport, a backend's own (called with the lock) ----------------------------
    @abstractmethod
    def _send(self, worker: Worker) -> None:
        """Give ``worker`` the work it has just taken: its ``request`` (``RUNNING``) or its
        tree's ``leaves`` (``RUNNING_TREE``)."""

    @abstractmethod
    def _send_other(self, worker: Worker) -> None:
        """Give ``worker`` (``TREE_PAUSED``) the projection ``other`` to pause its tree for."""

    @abstractmethod
    def _halt(self, worker: Worker) -> None:
        """Stop ``worker``'s process (it is ``STOPPING``); its end comes back as
        :meth:`_lost`."""

    @abstractmethod
    def _restart(self, worker: Worker) -> None:
        """Replace ``worker`` (now ``STARTING``) by a fresh one; it comes back as
        :meth:`_started` or :meth:`_start_failed`."""

    # -- what the transport reports (with the lock) ---------------------------------------
    def _started(self, worker: Worker) -> None:
        """``worker`` has started and warmed up."""
        worker.state, worker.projections, worker.error = WorkerState.IDLE, 0, None
        self._schedule()

    def _start_failed(self, worker: Worker, error: ProjectionError) -> None:
        """``worker`` could not start (or start again for the work it had taken, which
        fails with ``error`` or, a tree's, is queued again)."""
        if worker.request is not None:
            self._requests.fail(worker.request, error)
        leaves = list(worker.leaves.values())
        self._clear(worker, WorkerState.FAILED)
        worker.error = error
        self._again(leaves)
        self._schedule()

    def _answered(self, worker: Worker, request: Request,
                  result: ProjectionResult | ProjectionError) -> None:
        """``request``, the projection ``worker`` runs or pauses its tree for, has ended."""
        self._settle(worker, request, result)
        if request is worker.other:
            worker.other = None
            if worker.state is WorkerState.TREE_PAUSED:
                worker.state = WorkerState.RUNNING_TREE
                self._clock(worker)   # the pause does not count against the tree
                if worker.leaves and all(r.cancelled for r in worker.running()):
                    self._stop_worker(worker, None)   # cancelled while paused
        elif request is worker.request:
            worker.request = None
            if worker.state is WorkerState.RUNNING:
                self._idle(worker)
        self._schedule()

    def _leaf_answered(self, worker: Worker, index: int,
                       result: ProjectionResult | ProjectionError) -> None:
        """The projection ``index`` of ``worker``'s tree has ended."""
        request = worker.leaves.pop(index, None)
        if request is None:
            return   # queued again meanwhile
        self._settle(worker, request, result)
        if worker.state is WorkerState.RUNNING_TREE:
            self._clock(worker)
        self._schedule()

    def _tree_ended(self, worker: Worker) -> None:
        """``worker``'s tree has ended: the projections it did not finish are queued again,
        one by one."""
        if worker.state is WorkerState.STOPPING:
            return   # what is left fails or runs again when its end is seen
        leaves = list(worker.leaves.values())
        worker.leaves = {}
        if leaves:
            self._log.warning('a tree of projections ended without %d of them; they run '
                              'again one by one', len(leaves))
        self._again(leaves)
        if worker.state is WorkerState.TREE_PAUSED:   # its other projection runs on
            worker.request, worker.other = worker.other, None
            worker.state = WorkerState.RUNNING
        else:
            self._idle(worker)
        self._schedule()

    def _lost(self, worker: Worker, cause: str) -> None:
        """``worker``'s process ended under its work (a crash, or stopped by
        :meth:`_halt`; ``cause`` says how): its projection and the one its tree was paused
        for fail, its tree's unfinished ones are queued again; it starts again."""
        for request in (worker.request, worker.other):
            if request is not None:
                error = self._failure(worker, request, cause)
                if error.kind in (ErrorKind.WORKER_CRASHED, ErrorKind.TIMEOUT):
                    self._log.warning('%s; a new worker starts for the next projection', error)
                self._requests.fail(request, error)
        leaves = list(worker.leaves.values())
        if leaves and not self._closed:
            self._log.warning('the worker running a tree of projections stopped (%s); a new '
                              'worker runs its %d unfinished projections one by one', cause,
                              len(leaves))
        self._clear(worker, WorkerState.STARTING)
        self._again(leaves)
        self._schedule()

    def _overdue(self, worker: Worker, now: float) -> bool:
        """Stop ``worker`` if what it runs is over time at ``now``; whether it was."""
        if worker.state not in BUSY or now < worker.deadline:
            return False
        if worker.state is WorkerState.RUNNING_TREE:
            self._log.warning('a tree of %d projections ran over time', len(worker.leaves))
            overdue = None   # its projections run again, each with its own limit
        else:
            overdue = worker.request if worker.state is WorkerState.RUNNING else worker.other
        self._stop_worker(worker, overdue)
        return True

    # -- the policy -----------------------------------------------------------------------
    def _schedule(self) -> None:
        """Give queued projections to the workers that can take them, by owner in turn, a
        family's together; and while none is idle, pause a tree for another query's."""
        if self._closed:
            return
        self._queue = deque(r for r in self._queue if not r.future.done())
        started = False
        for worker in self._roster:
            if not self._queue:
                break
            if worker.state is WorkerState.FAILED:
                request = self._next(list(self._queue), self._queue)
                if request is not None:   # it says why, and the worker starts again
                    self._requests.fail(request, worker.error)
                    self._clear(worker, WorkerState.STARTING)
                    self._restart(worker)
            elif worker.state is WorkerState.IDLE and self._take(worker):
                started = True
                self._send(worker)
        if started:
            self._forget_owners([*self._queue, *self._running()])
        if not self._queue or any(w.state in (WorkerState.IDLE, WorkerState.FAILED)
                                  for w in self._roster):
            return   # an idle worker takes it
        for worker in self._roster:
            owners = worker.pausable_owners()
            if owners is None:
                continue
            request = self._next([r for r in self._queue if not r.owners & owners],
                                 self._queue)
            if request is None:
                continue
            self._count([request])
            worker.other, worker.state = request, WorkerState.TREE_PAUSED
            worker.deadline = time.monotonic() + request.timeout
            self._send_other(worker)

    def _take(self, worker: Worker) -> bool:
        """Have the idle ``worker`` take the next queued projection, with the queued ones
        of its family up to a fair share; False if none can run."""
        first = self._next(list(self._queue), self._queue)
        if first is None:
            return False
        taken = self._with_family(first, sum(len(w.running()) for w in self._roster))
        self._count(taken)
        worker.taken += 1
        if len(taken) == 1:
            worker.request, worker.state = first, WorkerState.RUNNING
        else:
            self._log.debug('a tree of %d projections from %s', len(taken), first.key[:12])
            worker.leaves, worker.state = dict(enumerate(taken)), WorkerState.RUNNING_TREE
        self._clock(worker)
        return True

    def _clock(self, worker: Worker) -> None:
        """Start the time limit of what ``worker`` runs now: a projection's own; a tree's,
        the longest of those it has left (``startup_timeout`` for its end if none)."""
        if worker.state is WorkerState.RUNNING:
            limit = worker.request.timeout
        elif worker.state is WorkerState.RUNNING_TREE:
            limit = max((r.timeout for r in worker.leaves.values()),
                        default=self.startup_timeout)
        else:
            return
        worker.deadline = time.monotonic() + limit

    def _next_deadline(self) -> float:
        """When the first of the workers' time limits passes (``inf`` if none runs)."""
        return min((w.deadline for w in self._roster if w.state in BUSY), default=math.inf)

    def _droppable(self, request: Request) -> bool:
        """Whether dropping an owner's projections (``cancel(owner, running=False)``) takes
        ``request``: it is queued, or one of a tree's, which makes them one after the other,
        with others left."""
        return request in self._queue or any(
            len(w.leaves) > 1 and request in w.leaves.values() for w in self._roster)

    def _stop(self, request: Request) -> bool:
        """For a cancel: stop the worker that runs ``request`` and say True; False if none
        runs it (it is dropped from the queue)."""
        for worker in self._roster:
            if request is worker.other:
                return True   # stopping it would stop the tree it pauses: it finishes
            if request is worker.request:
                if worker.state is WorkerState.RUNNING:
                    self._stop_worker(worker, None)
                return True
            if request in worker.leaves.values():
                # A tree stops once none of its unfinished projections is wanted any more
                # (one paused for another query's, once that has ended).
                if (worker.state is WorkerState.RUNNING_TREE
                        and all(r.cancelled for r in worker.running())):
                    self._stop_worker(worker, None)
                return True
        if request in self._queue:
            self._queue.remove(request)
        return False

    def _stop_worker(self, worker: Worker, overdue: Request | None) -> None:
        worker.state, worker.overdue = WorkerState.STOPPING, overdue
        self._halt(worker)

    def _idle(self, worker: Worker) -> None:
        """``worker`` has done its work: idle, or replaced if it has made its share."""
        worker.deadline = math.inf
        if worker.projections >= self.max_projections and not self._closed:
            self._clear(worker, WorkerState.STARTING)
            self._restart(worker)
        else:
            worker.state = WorkerState.IDLE

    def _clear(self, worker: Worker, state: WorkerState) -> None:
        worker.state, worker.request, worker.leaves, worker.other = state, None, {}, None
        worker.deadline, worker.overdue = math.inf, None
        if state is WorkerState.STARTING:
            worker.projections, worker.error = 0, None

    def _settle(self, worker: Worker, request: Request,
                result: ProjectionResult | ProjectionError) -> None:
        """Give ``request`` its ``result``, or fail it."""
        worker.projections += 1
        if isinstance(result, ProjectionResult):
            if not request.future.done():
                request.future.set_result(result)
        else:
            self._requests.fail(request, result)

    def _again(self, requests: list[Request]) -> None:
        """Queue a tree's unfinished ``requests`` again, first, each to run on its own; the
        cancelled ones fail (and all of them if the backend is closed)."""
        for request in reversed(requests):
            if request.future.done():
                continue
            if self._closed:
                self._requests.fail(request, ProjectionError(
                    ErrorKind.POOL_CLOSED, 'the projection backend was closed'))
            elif request.cancelled:
                self._requests.fail(request, ProjectionError(
                    ErrorKind.CANCELLED, f'projection {request.key[:12]} was cancelled'))
            else:
                request.family = None
                self._queue.appendleft(request)

    def _failure(self, worker: Worker, request: Request, cause: str) -> ProjectionError:
        """Why ``request`` failed when ``worker`` ended under it (``cause``)."""
        what = f'projection {request.key[:12]}'
        if self._closed:
            return ProjectionError(ErrorKind.POOL_CLOSED, f'the backend was closed during {what}')
        if request.cancelled:
            return ProjectionError(ErrorKind.CANCELLED, f'{what} was cancelled')
        if request is worker.overdue:
            return ProjectionError(ErrorKind.TIMEOUT,
                                   f'{what} took longer than {request.timeout:g} s')
        return ProjectionError(ErrorKind.WORKER_CRASHED, f'worker died during {what}: {cause}')

    def _running(self) -> list[Request]:
        return [r for w in self._roster for r in w.running()]

    def _fail_all(self, error: ProjectionError) -> None:
        """Fail every queued and running projection with ``error`` (closing)."""
        while self._queue:
            self._requests.fail(self._queue.popleft(), error)
        for request in self._running():
            self._requests.fail(request, error)

    # -- fair turns ------------------------------------------------------------------------
    def _next(self, candidates: list[Request], queue: deque[Request]) -> Request | None:
        """Of the ``candidates`` queued in ``queue``, the oldest of the owner (query) that
        has had the fewest projections taken so far, out of ``queue`` and marked running;
        None if none can run."""
        served = self._served
        while candidates:
            request = min(candidates, key=lambda r: min(served.get(o, 0) for o in r.owners))
            candidates.remove(request)
            queue.remove(request)
            # (One queued again after a tree left it unfinished is running already.)
            if request.future.running() or request.future.set_running_or_notify_cancel():
                return request
        return None

    def _count(self, taken: Iterable[Request]) -> None:
        """Count ``taken`` as taken for their owners."""
        for request in taken:
            for owner in request.owners:
                self._served[owner] = self._served.get(owner, 0) + 1

    def _forget_owners(self, live: Iterable[Request]) -> None:
        """Forget the counts of owners with none of ``live`` (the requests queued or under
        way) left."""
        owners = {o for r in live for o in r.owners}
        self._served = {o: n for o, n in self._served.items() if o in owners}

    def _with_family(self, first: Request, busy: int) -> list[Request]:
        """``first`` (taken) and the queued requests of its family, up to a fair share per
        worker of what is left to do (the queue, and ``busy`` projections under way), taken
        out of the queue and marked running."""
        if first.family is None:
            return [first]
        share = math.ceil((len(self._queue) + 1 + busy) / self.workers)
        taken, others = [first], deque()
        for request in self._queue:
            if (len(taken) < share and request.family == first.family
                    and request.future.set_running_or_notify_cancel()):
                taken.append(request)
            else:
                others.append(request)
        self._queue = others
        return taken
