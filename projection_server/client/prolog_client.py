"""A Python client for the query service and the projection action, after rosprolog_client.

>>> client = PrologClient()                  # after rclpy.init()
>>> client.once('member(X, [a, b])')
{'X': Atom('a')}
>>> client.all('member(X, [a, b])')
[{'X': Atom('a')}, {'X': Atom('b')}]
>>> with client.query('between(1, inf, X)') as solutions:   # incremental
...     for s in solutions:
...         if s['X'] > 2:
...             break                                  # finish is called on exit
>>> task = client.project('make_projection(grasping, grasp_object, [(F, force, [1, 5])], T)')
>>> task.feedback()                          # latest Project.Feedback, or None
>>> task.result()                            # solutions; task.cancel() stops it

The calls block. The client has its own node, spun by its own executor in a background
thread, so it works the same inside callbacks of your nodes, with any executor of yours, or
with none.

No call waits forever: while a query runs, the client pings the server and gives up with
:class:`PrologServerLost` when the server stops answering for ``service_timeout`` seconds;
``deadline`` (seconds) bounds a whole call. A query given up on by the client (deadline,
Ctrl-C) is finished on the server.
"""

from __future__ import annotations

import itertools
import os
import threading
import time
from typing import Any, Iterator
import uuid

from projection_interfaces.srv import PrologFinish, PrologNextSolution, PrologQuery
import rclpy
from rclpy.executors import SingleThreadedExecutor
from std_srvs.srv import Trigger

from projection_server.client.bindings import decode_solution
from projection_server.client.discovery import handshake, request_resending

__all__ = [
    'PrologClient',
    'PrologClientError',
    'PrologDeadlineError',
    'PrologQueryError',
    'PrologServerLost',
    'server_hint',
]

_PING_PERIOD = 2.0


class PrologClientError(Exception):
    """The service could not be reached or did not answer in time."""


class PrologServerLost(PrologClientError):
    """The server stopped answering while a call was waiting for it."""


class PrologDeadlineError(PrologClientError):
    """The client's deadline passed; the query was finished on the server."""


class PrologQueryError(Exception):
    """The server reported an error for the query."""

    def __init__(self, kind: str, message: str, error: str = ''):
        super().__init__(f'{kind}: {message}')
        self.kind = kind
        self.message = message
        self.error = error  # the error term, JSON-encoded


def server_hint(server: str) -> str:
    """Where to look when no server answers at ``server``."""
    domain = os.environ.get('ROS_DOMAIN_ID', '0 (unset)')
    return (f'is a projection_server running as {server} (`make run`) in ROS_DOMAIN_ID '
            f'{domain}, with the same ROS_AUTOMATIC_DISCOVERY_RANGE as this shell?')


class PrologClient:
    """Blocking calls to a projection_server's query services and projection action."""

    def __init__(self, server: str = '/projection_server', *, service_timeout: float = 10.0,
                 name: str | None = None, context=None):
        self.server = server.rstrip('/')
        self._service_timeout = service_timeout
        # Query ids are <name>/<n>, so finish('<name>/*') releases all of ours.
        self.name = name or f'prolog_client_{uuid.uuid4().hex[:8]}'
        self._ids = itertools.count(1)
        self._node = rclpy.create_node(self.name, context=context)
        self._query = self._node.create_client(PrologQuery, f'{self.server}/query')
        self._next = self._node.create_client(PrologNextSolution,
                                              f'{self.server}/next_solution')
        self._finish = self._node.create_client(PrologFinish, f'{self.server}/finish')
        self._ping = self._node.create_client(Trigger, f'{self.server}/ping')
        self._action = None
        self._discovered = False   # the server has matched our clients (discovery.py)
        self._project_tasks: dict[bytes, Any] = {}   # goal uuid -> ProjectTask
        self._lock = threading.Lock()
        self.truncated = False  # the last all() was stopped at the solution cap
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self._node)
        self._spinner = threading.Thread(target=self._executor.spin, daemon=True,
                                         name=f'{self.name}-spin')
        self._spinner.start()

    def close(self, finish: bool = True) -> None:
        """Finish this client's open queries (unless ``finish`` is False: the server is
        gone) and release its node."""
        if finish:
            try:
                self.finish_all()
            except PrologClientError:
                pass
        self._executor.shutdown()
        self._spinner.join(timeout=5.0)
        self._node.destroy_node()

    def __enter__(self) -> PrologClient:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def wait_for_server(self, timeout: float = 10.0) -> bool:
        """True once all the server's services are there, False after ``timeout`` s."""
        end = time.monotonic() + timeout
        return (all(c.wait_for_service(timeout_sec=max(0.0, end - time.monotonic()))
                    for c in (self._query, self._next, self._finish, self._ping))
                and self._handshake(max(0.0, end - time.monotonic())))

    def once(self, query: str, *, timeout: float = 0.0,
             deadline: float | None = None) -> dict[str, Any] | None:
        """The first solution, or None if the query has none."""
        response = self._start(PrologQuery.Request.ONCE, query, timeout, 0, deadline)
        return decode_solution(response.solutions[0]) if response.solutions else None

    def all(self, query: str, *, timeout: float = 0.0, max_solutions: int = 0,
            deadline: float | None = None) -> list[dict[str, Any]]:
        """All solutions, up to ``max_solutions`` (server default when 0).

        Whether the cap cut the answer short is in :attr:`truncated` afterwards.
        """
        response = self._start(PrologQuery.Request.ALL_SOLUTIONS, query, timeout,
                               max_solutions, deadline)
        return [decode_solution(s) for s in response.solutions]

    def query(self, query: str, *, timeout: float = 0.0) -> _Incremental:
        """An incremental query: iterate it in a ``with`` block."""
        response = self._start(PrologQuery.Request.INCREMENTAL, query, timeout, 0, None)
        return _Incremental(self, response.id)

    def project(self, query: str, *, once: bool = False, timeout: float = 0.0,
                max_solutions: int = 0, feedback_callback=None):
        """Send ``query`` to the ``~/project`` action; return its
        :class:`~projection_server.client.project_task.ProjectTask` at once."""
        from projection_server.client.project_task import ProjectTask

        if self._action is None:
            from projection_interfaces.action import Project
            from rclpy.action import ActionClient
            from rclpy.qos import QoSProfile
            self._action = ActionClient(self._node, Project, f'{self.server}/project')
            # rclpy's ActionClient drops a goal's feedback once its result is in, and the
            # last projection's feedback often travels with the result: the tasks read
            # the action's feedback topic themselves, with a history as deep as the
            # server's: a burst of cached projections' feedback must not overwrite itself.
            self._node.create_subscription(
                Project.Impl.FeedbackMessage, f'{self.server}/project/_action/feedback',
                self._on_project_feedback, QoSProfile(depth=1000))
            if not (self._action.wait_for_server(timeout_sec=self._service_timeout)
                    and handshake(self._node, self.server, self._service_timeout,
                                  self._until_done)):
                raise PrologClientError(f'action {self.server}/project is not available; '
                                        + server_hint(self.server))
        return ProjectTask(self, self._action, query, once=once, timeout=timeout,
                           max_solutions=max_solutions, query_id=self._new_id(),
                           feedback_callback=feedback_callback)

    def _on_project_feedback(self, message) -> None:
        with self._lock:
            task = self._project_tasks.get(bytes(message.goal_id.uuid))
        if task is not None:
            task._on_feedback(message)

    def _track(self, goal_uuid: bytes, task=None) -> None:
        """Route the feedback of goal ``goal_uuid`` to ``task`` (None: no longer)."""
        with self._lock:
            if task is None:
                self._project_tasks.pop(goal_uuid, None)
            else:
                self._project_tasks[goal_uuid] = task

    def finish(self, query_id: str) -> int:
        """Close the query ``query_id`` (or ``prefix*``) on the server; how many closed."""
        return self._call(self._finish, PrologFinish.Request(id=query_id)).closed

    def finish_all(self) -> int:
        """Close every query this client opened."""
        return self.finish(f'{self.name}/*')

    def ping(self) -> bool:
        """True when the server answers its ping within ``service_timeout`` seconds."""
        if not self._ping.wait_for_service(timeout_sec=self._service_timeout):
            return False
        response = request_resending(self._ping, Trigger.Request(), self._service_timeout,
                                     self._until_done)
        return response is not None and response.success

    # -- internals ----------------------------------------------------------------
    def _new_id(self) -> str:
        return f'{self.name}/{next(self._ids)}'

    def _start(self, mode: int, query: str, timeout: float, max_solutions: int,
               deadline: float | None):
        request = PrologQuery.Request(mode=mode, id=self._new_id(), query=query,
                                      timeout=float(timeout), max_solutions=max_solutions)
        # The server gives up on a solution after `timeout` (or its default); the
        # client waits for its answer as long as the server answers pings.
        try:
            response = self._call(self._query, request, wait=None, deadline=deadline)
        except (KeyboardInterrupt, PrologDeadlineError):
            self._finish_quietly(request.id)
            raise
        if not response.ok:
            raise PrologQueryError(response.error_kind, response.message, response.error)
        self.truncated = bool(response.truncated)
        return response

    def _finish_quietly(self, query_id: str) -> None:
        try:
            self._call(self._finish, PrologFinish.Request(id=query_id), wait=2.0)
        except PrologClientError:
            pass

    def _handshake(self, timeout: float) -> bool:
        # The ping client is this node's last: its answer proves the server has matched
        # the others (discovery.py). Once is enough; they live as long as the client.
        if not self._discovered:
            self._discovered = request_resending(self._ping, Trigger.Request(), timeout,
                                                 self._until_done) is not None
        return self._discovered

    @staticmethod
    def _until_done(future, seconds: float) -> bool:
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        return done.wait(seconds) or future.done()

    def _call(self, client, request, wait: float | None = 0.0,
              deadline: float | None = None):
        if not (client.wait_for_service(timeout_sec=self._service_timeout)
                and self._handshake(self._service_timeout)):
            raise PrologClientError(f'service {client.srv_name} is not available after '
                                    f'{self._service_timeout:g} s; {server_hint(self.server)}')
        future = client.call_async(request)
        try:
            return self.wait(future, client.srv_name, wait, deadline)
        finally:
            if not future.done():
                future.cancel()

    def wait(self, future, what: str, wait: float | None = 0.0,
             deadline: float | None = None):
        """The result of ``future``: within ``wait`` seconds (0: ``service_timeout``;
        None: as long as the server answers pings) and at most ``deadline`` seconds."""
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        start = time.monotonic()
        limit = None if wait is None else (wait or self._service_timeout)
        if deadline is not None:
            limit = deadline if limit is None else min(limit, deadline)
        ping = None
        while not done.wait(0.1 if limit is None else
                            max(0.0, min(0.1, start + limit - time.monotonic()))):
            now = time.monotonic()
            if limit is not None and now - start >= limit:
                if deadline is not None and now - start >= deadline:
                    raise PrologDeadlineError(f'no answer from {what} within the deadline '
                                              f'of {deadline:g} s')
                raise PrologClientError(f'no answer from {what} within {limit:g} s')
            if wait is None and what != self._ping.srv_name:
                ping = self._check_alive(ping, what)
        return future.result()

    def _check_alive(self, ping, what: str):
        """Keep one ping in flight; raise if one goes unanswered for service_timeout s."""
        now = time.monotonic()
        if ping is None:
            return (self._ping.call_async(Trigger.Request()), now)
        future, sent = ping
        if future.done():
            return None if now - sent >= _PING_PERIOD else ping
        if now - sent > self._service_timeout:
            future.cancel()
            raise PrologServerLost(
                f'{self.server} stopped answering (no ping reply for '
                f'{self._service_timeout:g} s) while waiting for {what}; '
                + server_hint(self.server))
        return ping


class _Incremental:
    """Iterator over an incremental query's solutions; finishes the query on exit."""

    def __init__(self, client: PrologClient, query_id: str):
        self._client = client
        self.id = query_id
        self._closed = False

    def __enter__(self) -> _Incremental:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __iter__(self) -> Iterator[dict[str, Any]]:
        while not self._closed:
            try:
                response = self._client._call(self._client._next,
                                              PrologNextSolution.Request(id=self.id),
                                              wait=None)
            except BaseException:
                self.close()
                raise
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
            self._client._finish_quietly(self.id)
