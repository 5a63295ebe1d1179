"""One goal of the ``~/project`` action, in nav2_simple_commander's shape.

>>> task = client.project(query)            # sent; returns at once
>>> while not task.is_done():
...     fb = task.feedback()                 # latest feedback, or None
>>> task.status                              # TaskResult.SUCCEEDED / CANCELED / FAILED
>>> task.result()                            # decoded solutions, or raises
"""

from __future__ import annotations

import enum
import threading
import time
import uuid
from typing import Any, Callable, TYPE_CHECKING

from action_msgs.msg import GoalStatus
from projection_interfaces.action import Project
from unique_identifier_msgs.msg import UUID

from projection_server.client.bindings import decode_solution
from projection_server.client.discovery import FIRST_RESEND, LAST_RESEND
from projection_server.client.prolog_client import (PrologClientError, PrologDeadlineError,
                                                    PrologQueryError)

if TYPE_CHECKING:
    from rclpy.action import ActionClient

    from projection_server.client.prolog_client import PrologClient

__all__ = ['ProjectTask', 'TaskResult', 'task_result']


class TaskResult(enum.Enum):
    """How a task ended (None while it runs)."""

    SUCCEEDED = 'succeeded'
    CANCELED = 'canceled'
    FAILED = 'failed'


def task_result(status: int) -> TaskResult | None:
    """The :class:`TaskResult` of an ``action_msgs/GoalStatus`` status."""
    return {GoalStatus.STATUS_SUCCEEDED: TaskResult.SUCCEEDED,
            GoalStatus.STATUS_CANCELED: TaskResult.CANCELED,
            GoalStatus.STATUS_ABORTED: TaskResult.FAILED}.get(status)


class ProjectTask:
    """A sent ``~/project`` goal: feedback, cancel, result."""

    def __init__(self, client: PrologClient, action: ActionClient, query: str, *,
                 once: bool, timeout: float, max_solutions: int, query_id: str,
                 feedback_callback: Callable[[Any], None] | None = None):
        self._client = client
        self.id = query_id
        self._feedback = None
        self._received = 0
        self._callback = feedback_callback
        self._lock = threading.Lock()
        goal = Project.Goal(mode=Project.Goal.ONCE if once else Project.Goal.ALL_SOLUTIONS,
                            id=query_id, query=query, timeout=float(timeout),
                            max_solutions=max_solutions)
        # The client routes this goal's feedback here, also feedback that comes with or
        # after the result (rclpy's own feedback callback would drop it).
        goal_uuid = UUID(uuid=list(uuid.uuid4().bytes))
        self._uuid = bytes(goal_uuid.uuid)
        client._track(self._uuid, self)
        try:
            self._handle = _send(action, goal, goal_uuid, client._service_timeout)
        except BaseException:
            client._track(self._uuid)
            raise
        self._result_future = self._handle.get_result_async()

    def _on_feedback(self, message: Any) -> None:
        with self._lock:
            self._feedback = message.feedback
            self._received += 1
        if self._callback is not None:
            self._callback(message.feedback)

    def feedback(self) -> Any:
        """The latest ``Project.Feedback`` (one per finished projection), or None."""
        with self._lock:
            return self._feedback

    def is_done(self) -> bool:
        return self._result_future.done()

    @property
    def status(self) -> TaskResult | None:
        if not self._result_future.done():
            return None
        return task_result(self._result_future.result().status)

    def cancel(self, wait: float = 5.0) -> bool:
        """Ask the server to stop; True when it accepted (the result then follows)."""
        if self.is_done():
            return False
        future = self._handle.cancel_goal_async()
        try:
            response = self._client.wait(future, 'the ~/project cancel', wait)
        except PrologClientError:
            return False
        return len(response.goals_canceling) > 0

    def wait(self, deadline: float | None = None) -> Any:
        """The raw ``Project.Result`` once the goal ends (cancelled on deadline or Ctrl-C)."""
        start = time.monotonic()
        try:
            result = self._client.wait(self._result_future, 'the ~/project action', None,
                                       deadline).result
            self._await_feedback(result.projections)
            return result
        except (KeyboardInterrupt, PrologDeadlineError):
            if self.cancel():
                try:   # the result says how far it got
                    self._client.wait(self._result_future, 'the ~/project action', 5.0)
                except PrologClientError:
                    pass
            self._client._track(self._uuid)   # its feedback no longer matters
            if deadline is not None and time.monotonic() - start >= deadline:
                raise PrologDeadlineError(f'no result within the deadline of {deadline:g} s;'
                                          ' the query was cancelled') from None
            raise

    def _await_feedback(self, count: int, patience: float = 5.0) -> None:
        # Feedback (a topic) and the result (a service) travel separately: the last
        # feedback may arrive just after the result; on a loaded machine (load 6 on 2
        # cores) more than a second after it.
        end = time.monotonic() + patience
        try:
            while time.monotonic() < end:
                with self._lock:
                    if self._received >= count:
                        return
                time.sleep(0.01)
        finally:
            self._client._track(self._uuid)

    def result(self, deadline: float | None = None) -> list[dict[str, Any]]:
        """The decoded solutions; raises :class:`PrologQueryError` (kind ``cancelled`` for
        a cancelled goal) when the goal did not succeed."""
        result = self.wait(deadline)
        if not result.ok:
            raise PrologQueryError(result.error_kind, result.message, result.error)
        return [decode_solution(s) for s in result.solutions]


def _send(action: ActionClient, goal: Any, goal_uuid: UUID, timeout: float) -> Any:
    """The handle of ``goal``, once the server has accepted it, sent again while its
    acceptance is not in: like any response, one can be lost (discovery.py). A goal sent
    again under its id is refused as a duplicate while the server holds it, so a refusal
    of a second sending means that an earlier one was accepted. (The server accepts every
    goal: a bad one is answered with its result.)"""
    answered = threading.Event()
    end = time.monotonic() + timeout
    period, sent = FIRST_RESEND, []
    while True:
        future = action.send_goal_async(goal, goal_uuid=goal_uuid)
        future.add_done_callback(lambda _: answered.set())
        sent.append(future)
        answered.wait(max(0.0, min(period, end - time.monotonic())))
        done = [f.result() for f in sent if f.done()]
        if any(handle.accepted for handle in done):
            return next(handle for handle in done if handle.accepted)
        if done and len(sent) == 1:
            raise PrologClientError('the ~/project action refused the goal')
        if done:
            return _held(action, goal_uuid, done[0])
        if time.monotonic() >= end:
            raise PrologClientError(f'no answer from the ~/project action within '
                                    f'{timeout:g} s')
        period = min(2 * period, LAST_RESEND)


def _held(action: ActionClient, goal_uuid: UUID, refusal: Any) -> Any:
    """A handle of the goal ``goal_uuid`` that the server holds, from the ``refusal`` of
    a copy sent under its id."""
    from rclpy.action.client import ClientGoalHandle

    accepted = Project.Impl.SendGoalService.Response(accepted=True, stamp=refusal.stamp)
    return ClientGoalHandle(action, goal_uuid, accepted)
