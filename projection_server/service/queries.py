"""Live Prolog queries: one thread and Prolog engine each, with limits and reaping.

This is the logic behind the query service, free of ROS: the node maps service
requests onto :class:`QueryManager` calls and their results onto responses.

The API, also used by the ``~/project`` action:

- :meth:`QueryManager.query` runs a request (ONCE, ALL or INCREMENTAL) and returns a
  :class:`QueryAnswer`; the request's fields are checked first (kind ``invalid_request``);
- :meth:`QueryManager.next_solution` and :meth:`QueryManager.finish` serve incremental
  queries; ``finish`` also stops running queries of any mode: their pending step returns
  at once with kind ``cancelled``, their engine is interrupted and their projections are
  cancelled (:func:`projection_server.projection.cancel`);
- ``QueryManager(limits, on_event=callback)`` reports each finished, cancelled, reaped or
  abandoned query as a :class:`QueryEvent` (the node logs them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import itertools
import math
import queue
import threading
import time
from typing import Any, Callable
import uuid

from projection_server import projection
from projection_server.service import progress, prolog_bridge

__all__ = [
    'ALL',
    'INCREMENTAL',
    'ONCE',
    'Outcome',
    'QueryAnswer',
    'QueryError',
    'QueryEvent',
    'QueryManager',
    'QuerySession',
    'ServerLimits',
    'nesting_depth',
]

ONCE = 'once'
ALL = 'all'
INCREMENTAL = 'incremental'
MODES = (ONCE, ALL, INCREMENTAL)

# C stack of a query thread. Prolog's parser and writer recurse on the C stack once per
# level of a term; a Python thread's default 8 MiB overflows near 20,000 levels and the
# process dies. Only the pages a query touches are used; they return when it ends.
QUERY_THREAD_STACK = 1024 ** 3
_stack_lock = threading.Lock()


class QueryError(Exception):
    """A request the manager refuses, with a machine-readable kind."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind
        self.message = message


@dataclass(frozen=True)
class Outcome:
    """What one step of a query produced."""

    status: str  # 'solution' | 'none' | 'error' | 'wrong_id'
    bindings: str = ''
    kind: str = ''
    message: str = ''
    error: str = ''

    @classmethod
    def from_prolog(cls, result: dict) -> Outcome:
        if result.get('status') == 'solution':
            return cls('solution', bindings=str(result['bindings']))
        return cls('error', kind=str(result.get('kind', 'system_error')),
                   message=str(result.get('message', '')), error=str(result.get('error', '')))


NO_MORE = Outcome('none')
_OPENED = Outcome('ok')


@dataclass
class QueryAnswer:
    """The result of a query request (all modes)."""

    id: str
    ok: bool = True
    message: str = ''
    kind: str = ''
    error: str = ''
    solutions: list[str] = field(default_factory=list)
    truncated: bool = False


@dataclass(frozen=True)
class QueryEvent:
    """A query that ended (or was opened, reaped, cancelled, abandoned), for the log."""

    event: str  # 'done' | 'opened' | 'cancelled' | 'reaped' | 'abandoned'
    id: str
    mode: str
    duration: float  # seconds since the request arrived
    kind: str = ''  # error kind; empty on success
    solutions: int = 0
    text: str = ''  # the query text (bounded by the node before logging)


@dataclass(frozen=True)
class ServerLimits:
    """Server-side defaults and limits (ROS parameters of the node)."""

    max_engines: int = 8
    default_timeout: float = 120.0
    max_solutions: int = 100
    idle_timeout: float = 300.0
    sandbox: bool = True
    # Extra seconds the server waits past a query's timeout for Prolog to stop
    # by itself before it reports the timeout and interrupts the engine.
    grace: float = 0.5
    # Hard bounds on request fields and on what a query may use.
    max_timeout: float = 3600.0
    max_solutions_limit: int = 10000
    max_query_length: int = 100_000  # characters of query text
    max_depth: int = 10_000  # nesting of brackets in query text
    max_id_length: int = 256
    stack_limit: int = 32 * 1024 ** 2  # bytes of Prolog stacks per engine
    max_answer: int = 1_000_000  # cells (about 8 bytes each) of one solution


_CLOSE = object()
_NEXT = object()


class QuerySession:
    """One query, run by its own thread on its own Prolog engine.

    Prolog requires an open query to be advanced and closed on the engine
    that opened it, so the thread keeps the query open between requests and
    takes commands from a queue.
    """

    _serial = itertools.count(1)

    def __init__(self, query_id: str, mode: str, text: str, options: dict[str, Any],
                 wait: float, on_exit: Callable[[QuerySession], None] | None = None):
        self.id = query_id
        self.mode = mode
        self.text = text
        self.wait = wait  # seconds to wait for one step before giving up on it
        self.owner = f'{query_id}#{next(self._serial)}'  # tags its projections
        # What Prolog passes on to every projection the query makes (query_service.pl).
        self.options = {**options, 'query': {'id': query_id, 'owner': self.owner}}
        self.started = time.monotonic()
        self.last_used = self.started
        self.solutions = 0
        self.finished = False  # no more solutions will come
        self.dead = False  # abandoned or cancelled: waiting for the thread to exit
        self.cancelled = False
        self.lock = threading.Lock()  # one request at a time per query
        self._on_exit = on_exit
        self._busy = False  # the thread is inside Prolog for a step
        self._commands: queue.Queue = queue.Queue()
        self._outcomes: queue.Queue = queue.Queue()
        self._engine: int | None = None
        self._thread = threading.Thread(target=self._run, name=f'query-{query_id}',
                                        daemon=True)

    # -- called from service threads -------------------------------------------------
    def start(self) -> Outcome:
        """Start the thread; return the outcome of parsing and checking the query."""
        with _stack_lock:
            previous = threading.stack_size(QUERY_THREAD_STACK)
            try:
                self._thread.start()
            finally:
                threading.stack_size(previous)
        return self._receive()

    def next(self) -> Outcome:
        """Compute the next solution."""
        self.last_used = time.monotonic()
        if self.finished:
            return NO_MORE
        self._commands.put(_NEXT)
        outcome = self._receive()
        if outcome.status == 'solution':
            self.solutions += 1
        else:
            self.finished = True
        self.last_used = time.monotonic()
        return outcome

    def close(self) -> None:
        """Release the query; the thread closes it and exits."""
        self.finished = True
        self._commands.put(_CLOSE)

    def cancel(self, kind: str = 'cancelled', message: str = '') -> None:
        """Stop the query now: a pending step returns ``kind`` at once; the engine is
        interrupted and the query's projections are cancelled."""
        self.cancelled = self.cancelled or kind == 'cancelled'
        self.finished = True
        self._outcomes.put(Outcome('error', kind=kind, message=message or
                                   'the query was finished by a client while it ran'))
        self._commands.put(_CLOSE)
        if self._busy:
            self.dead = True
            self.interrupt()
        projection.cancel(self.owner)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    @property
    def busy(self) -> bool:
        return self._busy

    def interrupt(self) -> None:
        """Ask Prolog to abandon what this query is doing now."""
        if self._engine is not None and self.alive:
            prolog_bridge.interrupt(self._engine)

    def _receive(self) -> Outcome:
        try:
            return self._outcomes.get(timeout=self.wait)
        except queue.Empty:
            # Prolog did not stop by itself (e.g. a goal that catches the time
            # limit, or a wait in Python); the session is given up and its engine
            # interrupted.
            limit = self.options.get('timeout', 0)
            self.cancel('timeout', f'Time limit exceeded: no answer within {limit:g} seconds; '
                                   'the query was abandoned')
            self.dead = True
            return self._outcomes.get()

    # -- the session thread ----------------------------------------------------------
    def _run(self) -> None:
        try:
            self._engine = prolog_bridge.attach_engine()
        except Exception as exc:  # noqa: BLE001 - reported to the client
            self._outcomes.put(Outcome('error', kind='resource_error',
                                       message=f'cannot create a Prolog engine: {exc}'))
            self._exit()
            return
        try:
            self._busy = True
            checked = prolog_bridge.check(self.text, self.options)
            self._busy = False
            if checked.get('status') != 'ok':
                self._outcomes.put(Outcome.from_prolog(checked))
                return
            self._outcomes.put(_OPENED)
            with prolog_bridge.solutions(self.text, self.options) as results:
                while self._commands.get() is _NEXT and not self.finished:
                    self._busy = True
                    result = next(results, None)
                    self._busy = False
                    if result is None:
                        self._outcomes.put(NO_MORE)
                        return
                    outcome = Outcome.from_prolog(result)
                    self._outcomes.put(outcome)
                    if outcome.status == 'error':
                        return
        except BaseException as exc:  # noqa: BLE001 - an abort, or a failure of the bridge
            if prolog_bridge.is_abort(exc):
                self._outcomes.put(Outcome('error', kind='aborted',
                                           message='the query was aborted'))
            else:
                self._outcomes.put(Outcome('error', kind='system_error',
                                           message=f'{type(exc).__name__}: {exc}'))
        finally:
            self._busy = False
            projection.drop(self.owner)   # what it prefetched and will not ask for
            projection.release(self.owner)
            progress.forget(self.owner)
            try:
                prolog_bridge.detach_engine()
            except BaseException:  # noqa: BLE001 - a pending abort may land here
                pass
            self._exit()

    def _exit(self) -> None:
        if self._on_exit is not None:
            self._on_exit(self)


_SENTINEL_OPEN = '([{'
_SENTINEL_CLOSE = ')]}'


def nesting_depth(text: str, limit: int) -> int:
    """Deepest bracket nesting of Prolog text outside quotes and comments (stops at limit+1).

    Approximate (it does not know operators), but cheap and on the safe side for brackets.
    """
    depth = deepest = 0
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c in _SENTINEL_OPEN:
            depth += 1
            if depth > deepest:
                deepest = depth
                if deepest > limit:
                    return deepest
        elif c in _SENTINEL_CLOSE:
            depth = max(depth - 1, 0)
        elif c == "'" and i > 0 and text[i - 1] == '0':  # 0'c: a character code
            i += 2 if text[i + 1:i + 2] == '\\' else 1
        elif c in '\'"`':
            i += 1
            while i < n and text[i] != c:
                i += 2 if text[i] == '\\' else 1
        elif c == '%':
            i = text.find('\n', i)
            i = n if i < 0 else i
        elif c == '/' and text.startswith('/*', i):
            i = text.find('*/', i + 2)
            i = n if i < 0 else i + 1
        i += 1
    return deepest


class QueryManager:
    """Owns all live queries and enforces the server's limits."""

    def __init__(self, limits: ServerLimits, clock: Callable[[], float] = time.monotonic,
                 on_event: Callable[[QueryEvent], None] | None = None):
        self.limits = limits
        self._clock = clock
        self._on_event = on_event
        self._lock = threading.Lock()
        self._open: dict[str, QuerySession] = {}  # incremental queries by id
        self._running: set[QuerySession] = set()  # every session holding an engine
        self._closed_idle: dict[str, float] = {}  # id -> when it was reaped
        self._counter = itertools.count(1)
        self._prefix = uuid.uuid4().hex[:8]

    # -- requests -----------------------------------------------------------------
    def query(self, mode: str, query_id: str, text: str, timeout: float = 0.0,
              max_solutions: int = 0) -> QueryAnswer:
        """Run a query request in ONCE, ALL or INCREMENTAL mode."""
        try:
            self.check_request(mode, query_id, text, timeout, max_solutions)
        except QueryError as exc:
            answer = QueryAnswer(id=query_id if isinstance(query_id, str) else '')
            self._event('done', answer.id, str(mode), time.monotonic(), exc.kind, 0,
                        text if isinstance(text, str) else '')
            return self._failed(answer, exc.kind, exc.message)
        query_id = query_id or f'{self._prefix}-{next(self._counter)}'
        answer = QueryAnswer(id=query_id)
        try:
            session = self._start(mode, query_id, text, timeout)
        except QueryError as exc:
            self._event('done', query_id, mode, time.monotonic(), exc.kind, 0, text)
            return self._failed(answer, exc.kind, exc.message)
        # Held from the start: a next_solution racing with the opening waits for it.
        with session.lock:
            checked = session.start()
            if checked.status != 'ok':
                self._release(session)
                self._log_end(session, checked.kind)
                return self._failed(answer, checked.kind, checked.message, checked.error)
            if mode == INCREMENTAL:
                answer.message = 'query opened'
                self._log_end(session, '', 'opened')
                return answer
            cap = 1 if mode == ONCE else (max_solutions or self.limits.max_solutions)
            try:
                while len(answer.solutions) < cap:
                    outcome = session.next()
                    if outcome.status == 'solution':
                        answer.solutions.append(outcome.bindings)
                    elif outcome.status == 'error':
                        self._log_end(session, outcome.kind)
                        return self._failed(answer, outcome.kind, outcome.message,
                                            outcome.error)
                    else:
                        break
                else:
                    answer.truncated = mode == ALL and not session.finished
            finally:
                self._release(session)
        n = len(answer.solutions)
        answer.message = f'{n} solution{"" if n == 1 else "s"}' + (
            f' (stopped at the cap of {cap}; max_solutions)' if answer.truncated else '')
        self._log_end(session, '')
        return answer

    def next_solution(self, query_id: str) -> Outcome:
        """Next solution of an incremental query; status 'wrong_id' if there is none."""
        with self._lock:
            session = self._open.get(query_id)
        if session is None:
            return Outcome('wrong_id', kind='wrong_id', message=self._unknown(query_id))
        with session.lock:
            if self._open.get(query_id) is not session:  # finished or reaped meanwhile
                return Outcome('wrong_id', kind='wrong_id', message=self._unknown(query_id))
            outcome = session.next()
            if outcome.status != 'solution':
                self._release(session)
                self._log_end(session, outcome.kind)
        return outcome

    def finish(self, query_id: str) -> int:
        """Close or stop queries: one by id, or all whose id matches ``prefix*``.

        An idle incremental query is closed; a running query of any mode is
        cancelled (its pending step returns kind ``cancelled``).
        """
        with self._lock:
            if query_id.endswith('*'):
                prefix = query_id[:-1]
                sessions = [s for s in self._running
                            if s.id.startswith(prefix) and not s.finished]
            else:
                sessions = [s for s in self._running if s.id == query_id and not s.finished]
        for session in sessions:
            self._stop(session)
        if not sessions and not query_id.endswith('*'):
            raise QueryError('wrong_id', self._unknown(query_id))
        return len(sessions)

    def reap(self) -> list[str]:
        """Close incremental queries idle longer than idle_timeout; return their ids."""
        now = self._clock()
        with self._lock:
            idle = [s for s in self._open.values()
                    if not s.lock.locked() and now - s.last_used > self.limits.idle_timeout]
            gone = [s for s in self._running if s.dead and not s.alive]
            for s in gone:
                self._running.discard(s)
        reaped = []
        for s in idle:
            if not s.lock.acquire(blocking=False):
                continue  # a request for it arrived meanwhile
            try:
                if self._open.get(s.id) is not s:
                    continue
                self._release(s)
            finally:
                s.lock.release()
            reaped.append(s.id)
            self._log_end(s, '', 'reaped')
            with self._lock:
                self._closed_idle[s.id] = now
        with self._lock:
            stuck = [s for s in self._running if s.dead]
            for qid, when in list(self._closed_idle.items()):
                if now - when > 10 * max(self.limits.idle_timeout, 60.0):
                    del self._closed_idle[qid]
        for s in stuck:
            s.interrupt()  # keep asking until the engine lets go
        return reaped

    def stats(self) -> dict[str, int]:
        with self._lock:
            return {'open_incremental': len(self._open), 'engines': len(self._running),
                    'abandoned': sum(1 for s in self._running if s.dead)}

    def shutdown(self) -> None:
        with self._lock:
            sessions = list(self._running)
        for s in sessions:
            s.cancel('cancelled', 'the server is shutting down')

    def check_request(self, mode: str, query_id: str, text: str, timeout: float,
                      max_solutions: int) -> None:
        """Raise QueryError('invalid_request') unless every field is within its range."""
        limits = self.limits

        def bad(message: str):
            raise QueryError('invalid_request', message)

        if mode not in MODES:
            bad(f'unknown query mode {mode!r} (ALL_SOLUTIONS=0, INCREMENTAL=1, ONCE=2)')
        self.check_id(query_id)
        if '*' in query_id:
            bad('a query id must not contain "*" (finish uses it to match prefixes)')
        if not isinstance(text, str):
            bad('the query text must be a string')
        if len(text) > limits.max_query_length:
            bad(f'the query text has {len(text)} characters; at most '
                f'{limits.max_query_length} are accepted (max_query_length)')
        if '\0' in text:
            raise QueryError('syntax_error', 'Syntax error: the query text contains a NUL '
                                             f'character at {text.index(chr(0))}')
        if nesting_depth(text, limits.max_depth) > limits.max_depth:
            bad(f'the query text nests brackets more than {limits.max_depth} levels deep '
                '(max_depth)')
        if (isinstance(timeout, bool) or not isinstance(timeout, (int, float))
                or not math.isfinite(timeout) or not 0 <= timeout <= limits.max_timeout):
            bad(f'timeout must be a number of seconds from 0 (the server default) to '
                f'{limits.max_timeout:g}, got {timeout!r}')
        if (isinstance(max_solutions, bool) or not isinstance(max_solutions, int)
                or not 0 <= max_solutions <= limits.max_solutions_limit):
            bad(f'max_solutions must be from 0 (the server default) to '
                f'{limits.max_solutions_limit}, got {max_solutions!r}')

    def check_id(self, query_id: str) -> None:
        """Raise QueryError('invalid_request') unless ``query_id`` is a valid id."""
        if not isinstance(query_id, str):
            raise QueryError('invalid_request', 'the query id must be a string')
        if len(query_id) > self.limits.max_id_length:
            raise QueryError('invalid_request', f'the query id is longer than '
                                                f'{self.limits.max_id_length} characters')
        if not query_id.isprintable():
            raise QueryError('invalid_request', 'the query id contains control characters')

    # -- internals ----------------------------------------------------------------
    def _start(self, mode: str, query_id: str, text: str, timeout: float) -> QuerySession:
        limits = self.limits
        timeout = timeout if timeout > 0 else limits.default_timeout
        options = {'timeout': float(timeout), 'sandbox': bool(limits.sandbox),
                   'stack_limit': int(limits.stack_limit), 'max_answer': int(limits.max_answer)}
        session = QuerySession(query_id, mode, text, options, wait=timeout + limits.grace,
                               on_exit=self._exited)
        with self._lock:
            if mode == INCREMENTAL and query_id in self._open:
                raise QueryError('wrong_id', f'a query with id {query_id!r} is already open')
            if len(self._running) >= limits.max_engines:
                raise QueryError(
                    'resource_error',
                    f'all {limits.max_engines} Prolog engines are busy '
                    '(parameter max_engines); finish open queries or retry later')
            self._running.add(session)
            if mode == INCREMENTAL:
                self._open[query_id] = session
                self._closed_idle.pop(query_id, None)
        return session

    def _stop(self, session: QuerySession) -> None:
        if session.busy or session.lock.locked():
            session.cancel()  # the request waiting for it logs the end
            with self._lock:
                if self._open.get(session.id) is session:
                    del self._open[session.id]
        else:
            self._release(session)
            self._log_end(session, '', 'done')

    def _release(self, session: QuerySession) -> None:
        session.close()
        with self._lock:
            if self._open.get(session.id) is session:
                del self._open[session.id]
            if not session.dead:
                self._running.discard(session)

    def _exited(self, session: QuerySession) -> None:
        with self._lock:
            self._running.discard(session)
            if self._open.get(session.id) is session and session.dead:
                del self._open[session.id]

    def _log_end(self, session: QuerySession, kind: str, event: str = 'done') -> None:
        if event == 'done' and session.dead and kind == 'timeout':
            event = 'abandoned'
        self._event(event, session.id, session.mode, session.started, kind,
                    session.solutions, session.text)

    def _event(self, event: str, query_id: str, mode: str, started: float, kind: str,
               solutions: int, text: str) -> None:
        if self._on_event is None:
            return
        try:
            self._on_event(QueryEvent(event, query_id, mode, time.monotonic() - started,
                                      kind, solutions, text))
        except Exception:  # noqa: BLE001 - logging must never fail a query
            pass

    def _unknown(self, query_id: str) -> str:
        if query_id in self._closed_idle:
            return (f'query {query_id!r} was closed after being idle for more than '
                    f'{self.limits.idle_timeout:g} seconds')
        return f'no open query with id {query_id!r}'

    @staticmethod
    def _failed(answer: QueryAnswer, kind: str, message: str, error: str = '') -> QueryAnswer:
        answer.ok = False
        answer.kind = kind
        answer.message = message
        answer.error = error
        return answer
