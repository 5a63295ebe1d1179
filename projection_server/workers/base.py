"""What every worker backend shares: the bag store, settings and limits, the requests by
job key under one lock, ``submit``'s bookkeeping, the context manager.

A backend subclasses :class:`BackendBase` and says how a new request reaches its workers
(:meth:`BackendBase._enqueue`), how many workers it has, how it stops a running projection
(:meth:`BackendBase._stop`) and how it closes.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections import deque
import math
import threading
from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.settings import load_settings
from projection_server.workers.bag_store import BagStore
from projection_server.workers.requests import check_timeout, Requests

if TYPE_CHECKING:
    from collections.abc import Iterable, Mapping, Sequence
    from concurrent.futures import Future
    import os

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings
    from projection_server.workers.backend import ProjectionResult
    from projection_server.workers.bag_store import Retention
    from projection_server.workers.requests import Request

__all__ = ['BackendBase']


class BackendBase(ABC):
    """``workers`` workers writing bags into ``bag_dir``; see
    :class:`~projection_server.workers.backend.WorkerBackend`."""

    def __init__(self, bag_dir: str | os.PathLike[str], workers: int,
                 settings: Settings | None, retention: Retention | Mapping[str, Any] | None,
                 startup_timeout: float, max_projections: int):
        if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
            raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'workers must be >= 1, got {workers!r}')
        self.store = BagStore(bag_dir, retention)
        self.bag_dir = self.store.bag_dir
        self.settings = settings if settings is not None else load_settings()
        self.startup_timeout = startup_timeout
        self.max_projections = max_projections
        self._lock = threading.Lock()
        self._requests = Requests(self.store)
        self._served: dict[str | None, int] = {}   # projections taken, by owner
        self._closed = False

    def __enter__(self) -> BackendBase:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    @abstractmethod
    def workers(self) -> int:
        """How many projections run at once (the useful prefetch depth)."""

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
        keys = [job.key(self.settings) for job in jobs]
        futures = []
        with self._lock:
            if self._closed:
                raise ProjectionError(ErrorKind.POOL_CLOSED, 'the projection backend is closed')
            for job, key in zip(jobs, keys):
                request, new = self._requests.add(job, key, timeout, owner)
                if new:
                    request.family = job.family(self.settings)
                    self._enqueue(request)
                futures.append(request.future)
        return futures

    @abstractmethod
    def _enqueue(self, request: Request) -> None:
        """Hand a new request to the workers (called with the lock)."""

    def cancel(self, owner: str, running: bool = True) -> int:
        """Cancel the unfinished projections that only ``owner`` asked for; how many.

        A queued one is dropped, a running one stops its worker (which is replaced); their
        futures fail with kind ``cancelled``. With ``running`` False only the queued ones
        are dropped: the running ones finish and their bags are kept (in the local pool, a
        tree of projections sharing their first steps stops once none of those it has not
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

    def _droppable(self, request: Request) -> bool:
        """Whether dropping an owner's projections (``cancel(owner, running=False)``) takes
        ``request``: if it is queued. Called with the lock."""
        return not request.future.running()

    def _next(self, candidates: list[Request], queue: deque[Request]) -> Request | None:
        """Of the ``candidates`` queued in ``queue``, the oldest of the owner (query) that
        has had the fewest projections taken so far, out of ``queue`` and marked running;
        None if none can run. Called with the lock."""
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
        """Count ``taken`` as taken for their owners (called with the lock)."""
        for request in taken:
            for owner in request.owners:
                self._served[owner] = self._served.get(owner, 0) + 1

    def _forget_owners(self, live: Iterable[Request]) -> None:
        """Forget the counts of owners with none of ``live`` (the requests queued or under
        way) left; called with the lock."""
        owners = {o for r in live for o in r.owners}
        self._served = {o: n for o, n in self._served.items() if o in owners}

    def _with_family(self, first: Request, queue: Iterable[Request], busy: int
                     ) -> tuple[list[Request], deque[Request]]:
        """``first`` (taken) and the queued requests of its family, up to a fair share per
        worker of what is left to do (``queue``, and ``busy`` projections under way in the
        other workers), marked running; and the rest of ``queue``. Called with the lock."""
        if first.family is None:
            return [first], deque(queue)
        queue = list(queue)
        share = math.ceil((len(queue) + 1 + busy) / self.workers)
        taken, others = [first], deque()
        for request in queue:
            if (len(taken) < share and request.family == first.family
                    and request.future.set_running_or_notify_cancel()):
                taken.append(request)
            else:
                others.append(request)
        return taken, others

    @abstractmethod
    def _stop(self, request: Request) -> bool:
        """Stop the worker that runs ``request`` and say True; False if none runs it (it
        is queued: drop it from the queue where that can be done). Called with the lock."""

    @abstractmethod
    def close(self) -> None:
        """Stop the workers; unfinished projections fail with kind ``pool_closed``."""
