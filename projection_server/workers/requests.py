"""The bookkeeping every backend shares: projections asked for, by job key, with who asked.

Identical submissions share one :class:`Request` (one future, one bag); a finished one is
kept for a while (:data:`KEEP_FINISHED`), and a bag already in the bag directory answers at
once. Backends call these with their own lock held.
"""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from projection_server.workers.backend import ProjectionResult

from projection_server.errors import ErrorKind, ProjectionError

if TYPE_CHECKING:
    from projection_server.simulation.job import Job
    from projection_server.workers.bag_store import BagStore

__all__ = ['KEEP_FINISHED', 'Request', 'Requests', 'check_timeout']

# Finished results kept for identical submissions (prefetched ones wait here to be asked
# for); beyond this the oldest go, and their bags answer from the bag directory.
KEEP_FINISHED = 256


def check_timeout(timeout: object) -> None:
    """A projection's time limit is a positive number of seconds.

    Raises:
        ProjectionError: kind ``invalid_parameters``.
    """
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or timeout <= 0:
        raise ProjectionError(ErrorKind.INVALID_PARAMETERS, f'timeout must be > 0 s: {timeout!r}')


@dataclass
class Request:
    """One projection asked for: its job and key, time limit, future and owners."""

    job: Job
    key: str
    timeout: float
    future: Future[ProjectionResult]
    owners: set[str | None] = field(default_factory=set)
    cancelled: bool = False
    family: str | None = None   # Job.family: projections that may share their first steps


class Requests:
    """A backend's requests by job key, answering from ``store`` where it can."""

    def __init__(self, store: BagStore):
        self._store = store
        self._by_key: dict[str, Request] = {}

    def add(self, job: Job, key: str, timeout: float, owner: str | None
            ) -> tuple[Request, bool]:
        """The request for ``job``; True if it is new and must be run (else it is running,
        queued, finished or answered from the bag directory)."""
        request = self._by_key.get(key)
        if request is not None and (not request.future.done() or _usable(request.future)):
            if request.future.done():
                self._store.touch(Path(request.future.result().bag))
            else:
                request.owners.add(owner)
            return request, False
        request = Request(job, key, float(timeout), Future(), {owner})
        self._by_key.pop(key, None)
        self._by_key[key] = request
        self._forget_finished()
        final = self._store.existing(job, key)
        if final is not None:
            request.future.set_result(ProjectionResult(str(final)))
            return request, False
        return request, True

    def only_for(self, owner: str) -> list[Request]:
        """The unfinished requests that ``owner`` alone asked for, not yet cancelled."""
        return [r for r in self._by_key.values()
                if not r.future.done() and not r.cancelled and r.owners == {owner}]

    def fail(self, request: Request, error: ProjectionError) -> None:
        """Fail ``request`` (queued, claimed or running) and forget it."""
        if self._by_key.get(request.key) is request:
            del self._by_key[request.key]
        if not request.future.done():
            if not request.future.running():
                request.future.set_running_or_notify_cancel()
            request.future.set_exception(error)

    def _forget_finished(self) -> None:
        finished = [key for key, r in self._by_key.items() if r.future.done()]
        for key in finished[:max(0, len(finished) - KEEP_FINISHED)]:
            del self._by_key[key]


def _usable(future: Future[ProjectionResult]) -> bool:
    """A finished future whose bag still exists (retention may have deleted it)."""
    return (not future.cancelled() and future.exception() is None
            and Path(future.result().bag).is_dir())
