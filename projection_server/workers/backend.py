"""The seam between the projection layer and whatever runs projections.

A backend is "a set of workers": it takes a :class:`~projection_server.simulation.job.Job`
and returns at once with a future of its :class:`ProjectionResult`; it can cancel the jobs
of one owner (a query) and be closed. Everything else (where the workers run, how they are
supervised, how a bag reaches the bag directory) is the backend's own business.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Sequence
    from concurrent.futures import Future
    from pathlib import Path

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings

__all__ = ['ProjectionResult', 'WorkerBackend']


@dataclass(frozen=True)
class ProjectionResult:
    """A finished projection: its bag in the bag directory and, when the worker made it
    from the samples it had in memory, its timeline (the dict of ``docs/contracts.md``).

    ``timeline`` is None for a bag found in the bag directory (made by an earlier process):
    its timeline is then read from the bag.
    """

    bag: str
    timeline: dict[str, Any] | None = None


@runtime_checkable
class WorkerBackend(Protocol):
    """What the projection layer needs from a set of projection workers."""

    bag_dir: Path
    settings: Settings

    @property
    def workers(self) -> int:
        """How many projections run at once (the useful prefetch depth)."""

    def submit(self, job: Job, timeout: float,
               owner: str | None = None) -> Future[ProjectionResult]:
        """Queue ``job`` and return at once. ``timeout`` limits its wall-clock simulation
        time from when a worker takes it; identical jobs share one future. ``owner`` tags the
        job with who asked for it (a query id), for :meth:`cancel`.

        Raises:
            ProjectionError: ``invalid_parameters`` for a bad timeout, ``pool_closed``.
        """

    def submit_all(self, jobs: Sequence[Job], timeout: float,
                   owner: str | None = None) -> list[Future[ProjectionResult]]:
        """:meth:`submit` each of ``jobs``, queued together."""

    def cancel(self, owner: str, running: bool = True) -> int:
        """Cancel the queued and running jobs that only ``owner`` asked for; their futures
        fail with kind ``cancelled``. Returns how many were cancelled. With ``running``
        False, only the queued ones (running ones finish and keep their bags)."""

    def close(self) -> None:
        """Stop the workers; unfinished jobs fail with kind ``pool_closed``."""
