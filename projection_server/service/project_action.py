"""The ``~/project`` action: a query with feedback after each projection, and cancel.

Goal: a query and a mode (ONCE or ALL_SOLUTIONS), as for ``~/query``. Feedback: one
message per finished projection (index/total, parameters, outcome, bag, elapsed time).
Result: the solutions, as ``~/query`` returns them. Cancelling the goal finishes its query:
it stops at the latest after the projection under way (see :mod:`projection_server.service.progress`).
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any, TYPE_CHECKING

from projection_interfaces.action import Project
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.qos import QoSProfile

from projection_server.service import progress
from projection_server.service.queries import ALL, ONCE, QueryAnswer, QueryError

if TYPE_CHECKING:
    from rclpy.node import Node

    from projection_server.service.queries import QueryManager

__all__ = ['ProjectActionServer']

_MODES = {Project.Goal.ALL_SOLUTIONS: ALL, Project.Goal.ONCE: ONCE}
# Cached projections report within milliseconds of each other: a history of rclpy's default
# 10 would drop the oldest feedback of a burst before a busy client has taken it.
FEEDBACK_DEPTH = 1000


class ProjectActionServer:
    """Serves ``~/project`` on ``node`` with the node's :class:`QueryManager`."""

    def __init__(self, node: Node, queries: QueryManager, callback_group: Any = None):
        self._node = node
        self._queries = queries
        self._lock = threading.Lock()
        self._cancelled: set[str] = set()  # query ids whose goal was cancelled
        self._server = ActionServer(node, Project, '~/project', self._execute,
                                    goal_callback=self._on_goal,
                                    cancel_callback=self._on_cancel,
                                    callback_group=callback_group,
                                    feedback_pub_qos_profile=QoSProfile(depth=FEEDBACK_DEPTH))

    def destroy(self) -> None:
        self._server.destroy()

    def _on_goal(self, goal: Project.Goal) -> GoalResponse:
        return GoalResponse.ACCEPT  # a bad goal is answered with a structured result

    def _on_cancel(self, goal_handle: Any) -> CancelResponse:
        query_id = self._query_id(goal_handle)
        with self._lock:
            self._cancelled.add(query_id)
        try:
            self._queries.finish(query_id)   # stops a running query where finish can
        except QueryError:
            pass   # not (or no longer) open: it stops at its next projection
        return CancelResponse.ACCEPT

    def _execute(self, goal_handle: Any) -> Project.Result:
        goal = goal_handle.request
        query_id = self._query_id(goal_handle)
        started = time.monotonic()
        mode = _MODES.get(goal.mode)
        sent = [0]

        def feedback(done: progress.ProjectionDone) -> None:
            with self._lock:
                if query_id in self._cancelled:
                    raise progress.QueryCancelled(f'query {query_id} was cancelled')
            sent[0] += 1
            goal_handle.publish_feedback(Project.Feedback(
                index=done.index, total=done.total, projections=done.count,
                program=done.program, parameters=json.dumps(done.parameters),
                outcome=' '.join(done.outcome), bag=done.bag,
                elapsed=time.monotonic() - started))

        if mode is None:
            answer = QueryAnswer(id=query_id, ok=False, kind='invalid_request', message=(
                f'unknown mode {goal.mode} for ~/project: ALL_SOLUTIONS (0) or ONCE (2); '
                'INCREMENTAL queries use ~/query and ~/next_solution'))
        else:
            with progress.listen(query_id, feedback):
                answer = self._queries.query(mode, query_id, goal.query, goal.timeout,
                                             goal.max_solutions)
        with self._lock:
            cancelled = query_id in self._cancelled
            self._cancelled.discard(query_id)
        result = Project.Result(ok=answer.ok and not cancelled, message=answer.message,
                                id=answer.id, error_kind=answer.kind, error=answer.error,
                                solutions=answer.solutions, truncated=answer.truncated,
                                projections=sent[0])
        if cancelled:
            # The query may stop before the server has moved the goal to CANCELING, which
            # it does once the cancel callback has returned; canceled() needs that state.
            until = time.monotonic() + 5.0
            while not goal_handle.is_cancel_requested and time.monotonic() < until:
                time.sleep(0.005)
            n = len(answer.solutions)
            result.error_kind, result.error = 'cancelled', ''
            result.message = (f'cancelled after {time.monotonic() - started:.1f} s with '
                              f'{n} solution{"" if n == 1 else "s"}')
            goal_handle.canceled()
        elif answer.ok:
            goal_handle.succeed()
        else:
            goal_handle.abort()
        return result

    @staticmethod
    def _query_id(goal_handle: Any) -> str:
        # The goal's id names its query, so that cancel finds the query from the goal alone.
        return goal_handle.request.id or f'project/{bytes(goal_handle.goal_id.uuid).hex()[:12]}'
