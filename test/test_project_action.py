"""The ~/project action: feedback after every projection of the paper's Table I query, cancel."""

from __future__ import annotations

import json
import time

import pytest

# Table I of Kunze et al. (2011): 6 forces x 3 positions.
TABLE_I = ('make_projection(grasping, grasp_object, [(F, force, [1, 3, 5, 7, 9, 11]), '
           '(P, position, [-0.02, 0.00, 0.02])], TL), '
           'not(occurs(break, _, TL)), not(occurs(slip, _, TL))')
# Forces no other test projects, so that nothing is cached and cancel meets running work.
UNCACHED = ('make_projection(grasping, grasp_object, [(F, force, [2.2, 4.2, 6.2, 8.2]), '
            '(P, position, [-0.015, 0.015])], TL)')


@pytest.fixture(scope='module')
def prolog(server):
    from projection_server.client import PrologClient

    client = PrologClient(server, service_timeout=20.0)
    assert client.wait_for_server(20.0)
    yield client
    client.close()


def test_table_i_sends_feedback_after_each_of_its_18_projections(prolog):
    from projection_server.client.project_task import TaskResult

    feedback = []
    task = prolog.project(TABLE_I, timeout=120.0, feedback_callback=feedback.append)
    solutions = task.result(deadline=600.0)
    assert task.status == TaskResult.SUCCEEDED and task.wait().projections == 18
    assert [f.index for f in feedback] == list(range(1, 19))
    assert {f.total for f in feedback} == {18}
    assert [f.projections for f in feedback] == list(range(1, 19))
    grid = [(p['force'], p['position']) for p in (json.loads(f.parameters) for f in feedback)]
    assert grid == [(f, p) for f in (1, 3, 5, 7, 9, 11) for p in (-0.02, 0.0, 0.02)]
    outcome = {g: set(f.outcome.split()) for g, f in zip(grid, feedback)}
    assert 'slip' in outcome[(1, 0.0)] and 'break' in outcome[(11, 0.0)]
    assert all(f.bag and f.program == 'grasp_object' for f in feedback)
    assert all(a.elapsed <= b.elapsed for a, b in zip(feedback, feedback[1:]))
    # The solutions are the projections whose outcome has neither break nor slip.
    good = {g for g, o in outcome.items() if not o & {'break', 'slip'}}
    assert {(s['F'], s['P']) for s in solutions} == good and good


def test_a_cancelled_goal_stops_and_frees_its_engine(prolog):
    from projection_server.client import PrologQueryError
    from projection_server.client.project_task import TaskResult

    feedback = []
    task = prolog.project(UNCACHED, timeout=120.0, feedback_callback=feedback.append)
    deadline = time.monotonic() + 300.0
    while len(feedback) < 2 and not task.is_done():
        assert time.monotonic() < deadline
        time.sleep(0.05)
    asked = time.monotonic()
    assert task.cancel()
    with pytest.raises(PrologQueryError) as info:
        task.result(deadline=60.0)
    stopped = time.monotonic() - asked
    assert task.status == TaskResult.CANCELED and info.value.kind == 'cancelled'
    result = task.wait()
    assert 2 <= len(result.solutions) < 8 and len(feedback) < 8
    assert stopped < 15.0, stopped   # a loose bound: bench/project_action.py measures it
    # The query's engine is released by its own thread, just after the result went out.
    free_by = time.monotonic() + 30.0   # a loaded machine's margin
    while json.loads(_ping(prolog))['engines'] and time.monotonic() < free_by:
        time.sleep(0.05)
    assert json.loads(_ping(prolog))['engines'] == 0
    assert prolog.once('X = still_serving') == {'X': 'still_serving'}


def test_a_goal_sent_again_under_its_id_is_refused_and_followed(prolog):
    # The client sends a goal again when its acceptance does not come: the server refuses
    # the copy, and the client follows the goal the server holds, which runs once.
    import uuid

    from action_msgs.msg import GoalStatus
    from projection_interfaces.action import Project
    from unique_identifier_msgs.msg import UUID

    from projection_server.client.project_task import _held

    assert prolog.project('X = 0').result(deadline=60.0) == [{'X': 0}]   # the action is up
    action = prolog._action
    goal = Project.Goal(mode=Project.Goal.ALL_SOLUTIONS, id='resent/1', timeout=30.0,
                        query='sleep(2), X = 1')
    goal_uuid = UUID(uuid=list(uuid.uuid4().bytes))
    first = prolog.wait(action.send_goal_async(goal, goal_uuid=goal_uuid), 'a goal', 20.0)
    copy = prolog.wait(action.send_goal_async(goal, goal_uuid=goal_uuid), 'its copy', 20.0)
    assert first.accepted and not copy.accepted
    time.sleep(0.5)
    assert json.loads(_ping(prolog))['engines'] == 1   # the goal runs once
    followed = _held(action, goal_uuid, copy)
    result = prolog.wait(followed.get_result_async(), 'the result', 30.0)
    assert result.status == GoalStatus.STATUS_SUCCEEDED
    assert [json.loads(s) for s in result.result.solutions] == [{'X': 1}]


def test_an_incremental_goal_ends_aborted_as_an_invalid_request(server, node):
    import rclpy
    from action_msgs.msg import GoalStatus
    from projection_interfaces.action import Project
    from rclpy.action import ActionClient

    from projection_server.client.discovery import handshake

    client = ActionClient(node, Project, f'{server}/project')
    assert client.wait_for_server(timeout_sec=20.0) and handshake(node, server, 20.0)
    sent = client.send_goal_async(Project.Goal(mode=1, query='X = 1'))
    rclpy.spin_until_future_complete(node, sent, timeout_sec=30.0)
    done = sent.result().get_result_async()
    rclpy.spin_until_future_complete(node, done, timeout_sec=30.0)
    assert done.result().status == GoalStatus.STATUS_ABORTED
    assert done.result().result.error_kind == 'invalid_request'
    client.destroy()


def _ping(prolog) -> str:
    from std_srvs.srv import Trigger
    return prolog._call(prolog._ping, Trigger.Request()).message
