"""Grippers whose fingers turn, through the real service: pybullet_data's xArm6 with its
own gripper (a four-bar linkage, one drive joint and mimic joints) and the KUKA iiwa with a
WSG50 (an SDF, two revolute finger joints) pick up the egg with a force that holds it, let
it slip with one too small and crush it with one too large, each given by its facts in the
query; each outcome is the same at a 2x finer step. The xArm does the same on MuJoCo (which
builds no SDF robot: test_engines_robots_service). Bad facts are errors that name them."""

from __future__ import annotations

import json

from projection_interfaces.srv import PrologQuery
import pytest

Q = PrologQuery.Request
SIM_TIMEOUT = 120.0
FINER = ', rate_hz: 480, solver_iterations: 200'
OUTCOME = ('( occurs(break(egg1), _, TL) -> O = break ; occurs(slip(egg1), _, TL) -> O = slip '
           '; occurs(lift(egg1), _, TL), \\+ occurs(collision(_, _), _, TL) -> O = lifted '
           '; O = other )')
XARM = '''entity(xarm1, robot, _{model: urdf, file: "xarm/xarm6_with_gripper.urdf",
    tool_link: xarm_gripper_base_link, tool_offset: [0, 0, 0.154],
    finger_joints: [drive_joint], pad_links: [left_finger, right_finger], max_force: 30,
    pose: _{xyz: [-0.68, 0, 0.72]}})'''
KUKA = '''entity(kuka1, robot, _{model: urdf, file: "kuka_iiwa/kuka_with_gripper2.sdf",
    tool_link: lbr_iiwa_link_7, tool_offset: [0, 0.022, 0.276], tool_rpy: [0, 0, 1.5708],
    finger_joints: [base_left_finger_joint, base_right_finger_joint],
    finger_open: [-0.3, 0.3], finger_closed: [0, 0], max_force: 30,
    home: [0, 0.41, 0, -1.59, 0, 1.14, 0], pose: _{xyz: [-0.8, 0, 0.72]}})'''
# The xArm's fingertips reach 2.3 cm past its pads: it grasps the egg 1 cm above its middle.
HEIGHT = {'xarm': 0.01, 'kuka': 0.0}
ROBOT = {'xarm': XARM, 'kuka': KUKA}


def grasp(height):
    return f'''plan([move_to(egg1, [0, 0, 0.10], [orientation(top), speed(0.5)]),
                     move_to(egg1, [0, 0, {height}], [speed(0.1)]),
                     close_gripper(F), wait(0.3), move_by([0, 0, 0.1]), wait(1.0)])'''


def ask(call, text, timeout=SIM_TIMEOUT):
    r = call(PrologQuery, 'query', Q(mode=Q.ALL_SOLUTIONS, query=text, timeout=timeout,
                                     max_solutions=100), timeout=timeout * 4)
    assert r.ok, (r.error_kind, r.message)
    return [json.loads(s) for s in r.solutions]


def sweep(call, robot, engine, forces, physics=''):
    sols = ask(call, f'''create_scenario(S), add_to_scenario(S, [kitchen_env, egg1,
        {ROBOT[robot]}]), make_projection(S, {grasp(HEIGHT[robot])},
        [(F, force, {forces})], [physics(_{{engine: {engine}{physics}}})], TL), {OUTCOME}''')
    return {s['F']: s['O'] for s in sols}


ROBOTS = [('xarm', 'pybullet'), ('xarm', 'mujoco'), ('kuka', 'pybullet')]


@pytest.mark.parametrize('robot, engine', ROBOTS)
def test_a_revolute_gripper_lets_the_egg_slip_lifts_it_and_crushes_it_as_force_grows(
        call, robot, engine):
    assert sweep(call, robot, engine, [0.3, 3, 15]) == {0.3: 'slip', 3: 'lifted',
                                                         15: 'break'}


# On MuJoCo the xArm's outcomes at a 4x finer step: test_engines_robots_service.
@pytest.mark.parametrize('robot, engine', [('xarm', 'pybullet'), ('kuka', 'pybullet')])
def test_a_revolute_grippers_outcomes_stay_at_a_2x_finer_step(call, robot, engine):
    assert sweep(call, robot, engine, [0.3, 3, 15], FINER) == {0.3: 'slip', 3: 'lifted',
                                                                15: 'break'}


def error_of(call, robot):
    r = call(PrologQuery, 'query', Q(mode=Q.ONCE, timeout=60.0, query=f'''create_scenario(S),
        add_to_scenario(S, [kitchen_env, egg1, {robot}]),
        make_projection(S, plan([wait(0.1)]), [], _)'''), timeout=120.0)
    assert not r.ok and r.error_kind == 'projection_error', r.message
    return r.message


def test_finger_joints_of_two_kinds_are_an_error_naming_the_property(call):
    message = error_of(call, XARM.replace('[drive_joint]', '[drive_joint, world_joint]'))
    assert 'finger_joints' in message and 'world_joint' in message, message


def test_finger_limits_that_are_no_range_need_finger_open_and_closed(call):
    message = error_of(call, KUKA.replace('finger_open: [-0.3, 0.3], finger_closed: [0, 0], ',
                                          ''))
    assert 'finger_open' in message and 'base_left_finger_joint' in message, message


def test_an_sdf_without_the_tool_link_is_an_error_naming_it(call):
    message = error_of(call, KUKA.replace('lbr_iiwa_link_7', 'flange'))
    assert 'tool_link' in message and 'flange' in message, message
    assert 'kuka_with_gripper2.sdf' in message, message


def test_the_node_serves_on_after_a_bad_gripper(call):
    error_of(call, KUKA.replace('lbr_iiwa_link_7', 'flange'))
    assert ask(call, 'X is 1 + 1') == [{'X': 2}]
