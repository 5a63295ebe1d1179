"""Progress of running queries, one report per finished projection.

Prolog's ``make_projection`` calls :func:`projection_done` after each projection, with the
context of the query that made it (its ``id`` and ``owner`` token, which the query service
gives Prolog for the query's run). A listener registered for that query's id (the ``~/project`` action's feedback)
receives a :class:`ProjectionDone`; a query with no listener only counts. The service
calls :func:`forget` when the query has ended.

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
    from collections.abc import Iterator, Mapping

__all__ = ['ProjectionDone', 'QueryCancelled', 'forget', 'listen', 'projection_done']

_log = logging.getLogger('projection_server.projection')
_lock = threading.Lock()
_listeners: dict[str, Callable[[ProjectionDone], None]] = {}
_counts: dict[str, int] = {}   # projections finished so far, by query owner token


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


def forget(owner: str) -> None:
    """Forget the count of the query whose owner token is ``owner``: it has ended."""
    with _lock:
        _counts.pop(owner, None)


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


def projection_done(query: Mapping[str, str] | None, index: int, total: int, program: str,
                    parameters: dict[str, Any], bag: str, outcome: list[str]) -> None:
    """Called by Prolog after each projection of ``make_projection`` of the query whose
    context is ``query`` (``id`` and ``owner``; None: made outside the service)."""
    query_id = query['id'] if query is not None else None
    _log.debug('query %s: projection %d/%d of %s %s: %s', query_id, index, total, program,
               parameters, ' '.join(outcome) or 'no events')
    if query is None:
        return
    with _lock:
        count = _counts[query['owner']] = _counts.get(query['owner'], 0) + 1
        callback = _listeners.get(query_id)
    if callback is not None:
        callback(ProjectionDone(query_id, int(index), int(total), count, str(program),
                                dict(parameters), [str(e) for e in outcome], str(bag)))
