"""Progress of running queries, one report per finished projection.

Prolog's ``make_projection`` calls :func:`projection_done` after each projection, in the
thread of the query that made it. A listener registered for that query's id (the
``~/project`` action's feedback) receives a :class:`ProjectionDone`; a query with no
listener only counts. The query's thread names its query with :func:`bind`.

    >>> with listen('me/1', print):
    ...     queries.query('all', 'me/1', 'make_projection(grasping, ...)')

A listener may stop the query by raising :class:`QueryCancelled`: Prolog receives it as
an error and the query ends there, between two projections.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
import logging
import threading
from typing import Any, Callable, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Iterator

__all__ = ['ProjectionDone', 'QueryCancelled', 'bind', 'listen', 'projection_done']

_log = logging.getLogger('projection_server.projection')
_local = threading.local()
_lock = threading.Lock()
_listeners: dict[str, Callable[[ProjectionDone], None]] = {}


class QueryCancelled(Exception):
    """Raised into a query that its client cancelled."""


@dataclass(frozen=True)
class ProjectionDone:
    """One finished projection of a query."""

    query_id: str
    index: int  # 1-based, within its make_projection call
    total: int  # projections that make_projection call enumerates
    count: int  # projections finished so far in this query
    program: str
    parameters: dict[str, Any]
    outcome: list[str]  # distinct event names of the timeline, in order
    bag: str


def bind(query_id: str | None) -> None:
    """Name the query the calling thread runs (None: none); resets its count."""
    _local.query_id = query_id
    _local.count = 0


@contextmanager
def listen(query_id: str, callback: Callable[[ProjectionDone], None]) -> Iterator[None]:
    """Call ``callback`` for each projection the query ``query_id`` finishes."""
    with _lock:
        _listeners[query_id] = callback
    try:
        yield
    finally:
        with _lock:
            if _listeners.get(query_id) is callback:
                del _listeners[query_id]


def projection_done(index: int, total: int, program: str, parameters: dict[str, Any],
                    bag: str, outcome: list[str]) -> None:
    """Called by Prolog after each projection of ``make_projection``."""
    query_id = getattr(_local, 'query_id', None)
    _local.count = getattr(_local, 'count', 0) + 1
    _log.debug('query %s: projection %d/%d of %s %s: %s', query_id, index, total, program,
               parameters, ' '.join(outcome) or 'no events')
    with _lock:
        callback = _listeners.get(query_id) if query_id is not None else None
    if callback is not None:
        callback(ProjectionDone(query_id, int(index), int(total), _local.count, str(program),
                                dict(parameters), [str(e) for e in outcome], str(bag)))
