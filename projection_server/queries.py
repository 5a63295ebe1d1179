"""Live Prolog queries: one thread and Prolog engine each, with limits and reaping.

This is the logic behind the query service, free of ROS: the node maps service
requests onto :class:`QueryManager` calls and their results onto responses.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import itertools
import queue
import threading
import time
from typing import Any, Callable
import uuid

from projection_server import prolog_bridge

__all__ = [
    'Outcome',
    'QueryAnswer',
    'QueryError',
    'QueryManager',
    'QuerySession',
    'ServerLimits',
]

ONCE = 'once'
ALL = 'all'
INCREMENTAL = 'incremental'


class QueryError(Exception):
    """A request the manager refuses, with a machine-readable kind."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind
        self.message = message


@dataclass(frozen=True)
class Outcome:
    """What one step of a query produced."""

    status: str  # 'solution' | 'none' | 'error'
    bindings: str = ''
    kind: str = ''
    message: str = ''
    error: str = ''

    @classmethod
    def from_prolog(cls, result: dict) -> 'Outcome':
        if result.get('status') == 'solution':
            return cls('solution', bindings=str(result['bindings']))
        return cls('error', kind=str(result.get('kind', 'system_error')),
                   message=str(result.get('message', '')), error=str(result.get('error', '')))


NO_MORE = Outcome('none')


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
class ServerLimits:
    """Server-side defaults and limits (ROS parameters of the node)."""

    max_engines: int = 8
    default_timeout: float = 120.0
    max_solutions: int = 100
    idle_timeout: float = 300.0
    sandbox: bool = True
    # Extra seconds the server waits past a query's timeout for Prolog to stop
    # by itself before it reports the timeout and interrupts the engine.
    grace: float = 2.0


_CLOSE = object()
_NEXT = object()


class QuerySession:
    """One query, run by its own thread on its own Prolog engine.

    Prolog requires an open query to be advanced and closed on the engine
    that opened it, so the thread keeps the query open between requests and
    takes commands from a queue.
    """

    def __init__(self, query_id: str, text: str, options: dict[str, Any], wait: float):
        self.id = query_id
        self.text = text
        self.options = options
        self.wait = wait  # seconds to wait for one step before giving up on it
        self.last_used = time.monotonic()
        self.finished = False  # no more solutions will come
        self.dead = False  # abandoned: waiting for the thread to exit
        self.lock = threading.Lock()  # one request at a time per query
        self._commands: queue.Queue = queue.Queue()
        self._outcomes: queue.Queue = queue.Queue()
        self._engine: int | None = None
        self._thread = threading.Thread(target=self._run, name=f'query-{query_id}',
                                        daemon=True)

    # -- called from service threads -------------------------------------------------
    def start(self) -> Outcome:
        """Start the thread; return the outcome of parsing and checking the query."""
        self._thread.start()
        return self._receive()

    def next(self) -> Outcome:
        """Compute the next solution."""
        self.last_used = time.monotonic()
        if self.finished:
            return NO_MORE
        self._commands.put(_NEXT)
        outcome = self._receive()
        if outcome.status != 'solution':
            self.finished = True
        self.last_used = time.monotonic()
        return outcome

    def close(self) -> None:
        """Release the query; the thread closes it and exits."""
        self.finished = True
        self._commands.put(_CLOSE)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    def interrupt(self) -> None:
        """Ask Prolog to abandon what this query is doing now."""
        if self._engine is not None and self.alive:
            prolog_bridge.interrupt(self._engine)

    def _receive(self) -> Outcome:
        try:
            return self._outcomes.get(timeout=self.wait)
        except queue.Empty:
            # Prolog did not stop by itself (e.g. a goal that catches the time
            # limit); the session is given up and its engine interrupted.
            self.dead = True
            self.finished = True
            self._commands.put(_CLOSE)
            self.interrupt()
            limit = self.options.get('timeout', 0)
            return Outcome('error', kind='timeout',
                           message=f'Time limit exceeded: no answer within {limit} seconds; '
                                   'the query was abandoned')

    # -- the session thread ----------------------------------------------------------
    def _run(self) -> None:
        try:
            self._engine = prolog_bridge.attach_engine()
        except Exception as exc:  # noqa: BLE001 - reported to the client
            self._outcomes.put(Outcome('error', kind='resource_error',
                                       message=f'cannot create a Prolog engine: {exc}'))
            return
        try:
            checked = prolog_bridge.check(self.text, self.options)
            if checked.get('status') != 'ok':
                self._outcomes.put(Outcome.from_prolog(checked))
                return
            self._outcomes.put(Outcome('ok'))
            with prolog_bridge.solutions(self.text, self.options) as results:
                while self._commands.get() is _NEXT:
                    result = next(results, None)
                    if result is None:
                        self._outcomes.put(NO_MORE)
                        return
                    outcome = Outcome.from_prolog(result)
                    self._outcomes.put(outcome)
                    if outcome.status == 'error':
                        return
        except Exception as exc:  # noqa: BLE001 - a failure of the bridge itself
            self._outcomes.put(Outcome('error', kind='system_error', message=str(exc)))
        finally:
            prolog_bridge.detach_engine()


class QueryManager:
    """Owns all live queries and enforces the server's limits."""

    def __init__(self, limits: ServerLimits, clock: Callable[[], float] = time.monotonic):
        self.limits = limits
        self._clock = clock
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
        query_id = query_id or f'{self._prefix}-{next(self._counter)}'
        answer = QueryAnswer(id=query_id)
        try:
            session = self._start(mode, query_id, text, timeout)
        except QueryError as exc:
            return self._failed(answer, exc.kind, exc.message)
        checked = session.start()
        if checked.status == 'error':
            self._release(session)
            return self._failed(answer, checked.kind, checked.message, checked.error)
        if mode == INCREMENTAL:
            answer.message = 'query opened'
            return answer
        cap = 1 if mode == ONCE else (max_solutions or self.limits.max_solutions)
        try:
            with session.lock:
                while len(answer.solutions) < cap:
                    outcome = session.next()
                    if outcome.status == 'solution':
                        answer.solutions.append(outcome.bindings)
                    elif outcome.status == 'error':
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
            f' (stopped at the cap of {cap})' if answer.truncated else '')
        return answer

    def next_solution(self, query_id: str) -> Outcome:
        """Next solution of an incremental query; status 'wrong_id' if there is none."""
        with self._lock:
            session = self._open.get(query_id)
        if session is None:
            return Outcome('wrong_id', kind='wrong_id', message=self._unknown(query_id))
        with session.lock:
            outcome = session.next()
        if outcome.status != 'solution':
            self._release(session)
        return outcome

    def finish(self, query_id: str) -> int:
        """Close one incremental query, or all whose id matches ``prefix*``."""
        with self._lock:
            if query_id.endswith('*'):
                prefix = query_id[:-1]
                ids = [i for i in self._open if i.startswith(prefix)]
            else:
                ids = [query_id] if query_id in self._open else []
            sessions = [self._open[i] for i in ids]
        for session in sessions:
            self._release(session)
        if not ids and not query_id.endswith('*'):
            raise QueryError('wrong_id', self._unknown(query_id))
        return len(ids)

    def reap(self) -> list[str]:
        """Close incremental queries idle longer than idle_timeout; return their ids."""
        now = self._clock()
        with self._lock:
            idle = [s for s in self._open.values()
                    if not s.lock.locked() and now - s.last_used > self.limits.idle_timeout]
            gone = [s for s in self._running if s.dead and not s.alive]
            for s in gone:
                self._running.discard(s)
        for s in idle:
            self._release(s)
            with self._lock:
                self._closed_idle[s.id] = now
        with self._lock:
            for s in self._running:
                if s.dead:
                    s.interrupt()  # keep asking until the engine lets go
            for qid, when in list(self._closed_idle.items()):
                if now - when > 10 * max(self.limits.idle_timeout, 60.0):
                    del self._closed_idle[qid]
        return [s.id for s in idle]

    def stats(self) -> dict[str, int]:
        with self._lock:
            return {'open_incremental': len(self._open), 'engines': len(self._running),
                    'abandoned': sum(1 for s in self._running if s.dead)}

    def shutdown(self) -> None:
        with self._lock:
            sessions = list(self._running)
        for s in sessions:
            s.close()
            s.interrupt()

    # -- internals ----------------------------------------------------------------
    def _start(self, mode: str, query_id: str, text: str, timeout: float) -> QuerySession:
        if mode not in (ONCE, ALL, INCREMENTAL):
            raise QueryError('domain_error', f'unknown query mode {mode!r}')
        timeout = timeout if timeout and timeout > 0 else self.limits.default_timeout
        options = {'timeout': float(timeout), 'sandbox': bool(self.limits.sandbox)}
        session = QuerySession(query_id, text, options, wait=timeout + self.limits.grace)
        with self._lock:
            if mode == INCREMENTAL and query_id in self._open:
                raise QueryError('wrong_id', f'a query with id {query_id!r} is already open')
            if len(self._running) >= self.limits.max_engines:
                raise QueryError(
                    'resource_error',
                    f'all {self.limits.max_engines} Prolog engines are busy '
                    '(parameter max_engines); finish open queries or retry later')
            self._running.add(session)
            if mode == INCREMENTAL:
                self._open[query_id] = session
                self._closed_idle.pop(query_id, None)
        return session

    def _release(self, session: QuerySession) -> None:
        session.close()
        with self._lock:
            if self._open.get(session.id) is session:
                del self._open[session.id]
            if not session.dead:
                self._running.discard(session)

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
