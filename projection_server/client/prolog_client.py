"""A Python client for the query service, in the spirit of rosprolog_client.

>>> client = PrologClient()                  # after rclpy.init()
>>> client.once('member(X, [a, b])')
{'X': Atom('a')}
>>> client.all('member(X, [a, b])')
[{'X': Atom('a')}, {'X': Atom('b')}]
>>> with client.query('between(1, inf, X)') as solutions:   # incremental
...     for s in solutions:
...         if s['X'] > 2:
...             break                                  # finish is called on exit

The calls block. The client has its own node, spun by its own executor in a
background thread, so it works the same inside callbacks of your nodes, with
any executor of yours, or with none.
"""

from __future__ import annotations

import itertools
import threading
from typing import Any, Iterator
import uuid

from projection_interfaces.srv import PrologFinish, PrologNextSolution, PrologQuery
import rclpy
from rclpy.executors import SingleThreadedExecutor

from projection_server.bindings import decode_solution

__all__ = ['PrologClient', 'PrologClientError', 'PrologQueryError']


class PrologClientError(Exception):
    """The service could not be reached or did not answer in time."""


class PrologQueryError(Exception):
    """The server reported an error for the query."""

    def __init__(self, kind: str, message: str, error: str = ''):
        super().__init__(f'{kind}: {message}')
        self.kind = kind
        self.message = message
        self.error = error  # the error term, JSON-encoded


class PrologClient:
    """Blocking calls to a projection_server's query services."""

    def __init__(self, server: str = '/projection_server', *, service_timeout: float = 10.0,
                 name: str | None = None, context=None):
        self._service_timeout = service_timeout
        # Query ids are <name>/<n>, so finish('<name>/*') releases all of ours.
        self.name = name or f'prolog_client_{uuid.uuid4().hex[:8]}'
        self._ids = itertools.count(1)
        self._node = rclpy.create_node(self.name, context=context)
        self._query = self._node.create_client(PrologQuery, f'{server}/query')
        self._next = self._node.create_client(PrologNextSolution, f'{server}/next_solution')
        self._finish = self._node.create_client(PrologFinish, f'{server}/finish')
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self._node)
        self._spinner = threading.Thread(target=self._executor.spin, daemon=True,
                                         name=f'{self.name}-spin')
        self._spinner.start()

    def close(self) -> None:
        """Finish this client's open queries and release its node."""
        try:
            self.finish_all()
        except PrologClientError:
            pass
        self._executor.shutdown()
        self._spinner.join(timeout=5.0)
        self._node.destroy_node()

    def __enter__(self) -> 'PrologClient':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def wait_for_server(self, timeout: float = 10.0) -> bool:
        return all(c.wait_for_service(timeout_sec=timeout)
                   for c in (self._query, self._next, self._finish))

    def once(self, query: str, *, timeout: float = 0.0) -> dict[str, Any] | None:
        """The first solution, or None if the query has none."""
        response = self._start(PrologQuery.Request.ONCE, query, timeout)
        return decode_solution(response.solutions[0]) if response.solutions else None

    def all(self, query: str, *, timeout: float = 0.0,
            max_solutions: int = 0) -> list[dict[str, Any]]:
        """All solutions, up to ``max_solutions`` (server default when 0)."""
        response = self._start(PrologQuery.Request.ALL_SOLUTIONS, query, timeout,
                               max_solutions)
        return [decode_solution(s) for s in response.solutions]

    def query(self, query: str, *, timeout: float = 0.0) -> '_Incremental':
        """An incremental query: iterate it in a ``with`` block."""
        response = self._start(PrologQuery.Request.INCREMENTAL, query, timeout)
        return _Incremental(self, response.id)

    def finish_all(self) -> int:
        """Close every incremental query this client opened."""
        return self._call(self._finish, PrologFinish.Request(id=f'{self.name}/*')).closed

    # -- internals ----------------------------------------------------------------
    def _start(self, mode: int, query: str, timeout: float, max_solutions: int = 0):
        request = PrologQuery.Request(mode=mode, id=f'{self.name}/{next(self._ids)}',
                                      query=query, timeout=float(timeout),
                                      max_solutions=max_solutions)
        # The server gives up on a solution after `timeout` (or its default);
        # wait for its answer rather than guessing a shorter deadline here.
        response = self._call(self._query, request, wait=None)
        if not response.ok:
            raise PrologQueryError(response.error_kind, response.message, response.error)
        return response

    def _call(self, client, request, wait: float | None = 0.0):
        if not client.wait_for_service(timeout_sec=self._service_timeout):
            raise PrologClientError(f'service {client.srv_name} is not available')
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        done.wait(None if wait is None else (wait or self._service_timeout))
        if not future.done():
            future.cancel()
            raise PrologClientError(f'no answer from {client.srv_name}')
        return future.result()


class _Incremental:
    """Iterator over an incremental query's solutions; finishes the query on exit."""

    def __init__(self, client: PrologClient, query_id: str):
        self._client = client
        self.id = query_id
        self._closed = False

    def __enter__(self) -> '_Incremental':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __iter__(self) -> Iterator[dict[str, Any]]:
        while not self._closed:
            response = self._client._call(self._client._next,
                                          PrologNextSolution.Request(id=self.id), wait=None)
            if response.status == PrologNextSolution.Response.OK:
                yield decode_solution(response.solution)
            elif response.status == PrologNextSolution.Response.NO_SOLUTION:
                self._closed = True
            else:
                self._closed = True
                raise PrologQueryError(response.error_kind, response.message)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._client._call(self._client._finish, PrologFinish.Request(id=self.id))
