"""The stand-in robot's logic without ROS: its robot's transforms, its resets, its plans'
text."""

from __future__ import annotations

import math

import numpy as np
import pytest

from projection_server.errors import ProjectionError
from projection_server.standin.description import matrix_of, RobotTree
from projection_server.standin.plan_text import parse_plan, PlanTextError
from projection_server.geometry import quaternion_of_rpy, rpy_of
from projection_server.standin.world import event_text, HOME, StandinConfig, StandinWorld


@pytest.fixture(scope='module')
def world():
    return StandinWorld(StandinConfig(real_time=False))


def test_the_link_frames_are_those_pybullet_computes_at_the_same_joints(world):
    import pybullet
    from pybullet_utils.bullet_client import BulletClient
    c = BulletClient(pybullet.DIRECT)
    try:
        body = c.loadURDF(world.robot_file, [-0.68, 0.0, 0.72], useFixedBase=True)
        world.reset(5)
        values = world.tree.values(world.state.joints)
        index = {c.getJointInfo(body, j)[1].decode(): j for j in range(c.getNumJoints(body))}
        for name, value in values.items():
            c.resetJointState(body, index[name], value)
        frames = world.tree.link_frames(world.base, world.state.joints)
        for name, j in index.items():
            state = c.getLinkState(body, j, computeForwardKinematics=True)
            link = c.getJointInfo(body, j)[12].decode()
            assert np.allclose(state[4], frames[link][:3, 3], atol=1e-6), link
    finally:
        c.disconnect()


def test_joint_states_carry_the_joints_neither_fixed_nor_mimic(world):
    assert world.tree.state_joints == [f'panda_joint{i}' for i in range(1, 8)] + [
        'panda_finger_joint1']
    moving = {child for _, child, _, _ in world.tree.transforms({})}
    assert 'panda_rightfinger' in moving   # panda_finger_joint2 follows joint1


def test_the_description_names_its_meshes_by_package_as_the_server_resolves_them(world):
    from projection_server.world.description import parse, resolve_mesh
    text = world.tree.description('franka_panda')
    parsed = parse(text)
    assert parsed.moving_joints() == world.tree.state_joints
    assert resolve_mesh('package://franka_panda/meshes/visual/link1.obj').endswith(
        'franka_panda/meshes/visual/link1.obj')


def test_a_reset_draws_the_same_world_from_the_same_seed_within_the_ranges(world):
    first, again, other = world.reset(3), world.reset(3), world.reset(4)
    assert first == again and first != other
    config = world.config
    egg = first['object']
    for key in ('friction', 'mass', 'breaking_force'):
        low, high = getattr(config, key)
        assert low <= egg['properties'][key] <= high
    x, y, z = egg['pose']['xyz']
    assert config.x[0] <= x <= config.x[1] and config.y[0] <= y <= config.y[1]
    assert z == pytest.approx(0.742)
    arm = first['joints']['positions'][:7]
    assert max(abs(a - h) for a, h in zip(arm, HOME)) >= 0.2


def test_the_scenario_starts_the_robot_at_its_joints_and_the_egg_at_its_truth(world):
    drawn = world.reset(8)
    robot, egg = world.scenario()['entities'][1:]
    assert robot['properties']['joint_names'] == drawn['joints']['names']
    assert robot['properties']['joint_positions'] == drawn['joints']['positions']
    assert egg['properties']['friction'] == drawn['object']['properties']['friction']
    assert egg['pose']['xyz'] == drawn['object']['pose']['xyz']


def test_ranges_out_of_order_are_refused():
    with pytest.raises(ProjectionError, match='friction'):
        StandinConfig(friction=(0.5, 0.1))


def test_the_plan_language_and_its_json_form_give_the_same_steps():
    text = parse_plan('[move_to(egg1, [0, 0, 0.1], [orientation(top)]), close_gripper(2 + 3)]')
    data = parse_plan('[{"action": "move_to", "object": "egg1", "offset": [0, 0, 0.1], '
                      '"orientation": "top"}, {"action": "close_gripper", "force": 5}]')
    assert text.steps == data.steps
    assert text.texts == ['move_to(egg1,[0,0,0.1],[orientation(top)])', 'close_gripper(2+3)']


@pytest.mark.parametrize('text, words', [
    ('[fly(1)]', 'malformed plan step fly(1)'),
    ('[wait(X)]', 'names variables (X)'),
    ('[wait(', 'Syntax error'),
    ('[]', '1 to 100 steps'),
    ('halt', "`list' expected"),
    ('[wait(-1)]', 'outside (0, 120]'),
])
def test_a_bad_plan_text_is_an_error_that_says_why(text, words):
    with pytest.raises(ProjectionError) as caught:
        parse_plan(text)
    assert words in caught.value.message
    assert isinstance(caught.value, PlanTextError) or 'outside' in words


def test_events_read_as_name_args_at_their_times():
    assert event_text(['grasp', ['egg1'], 1.234, 1.234]) == 'grasp(egg1)@1.23'
    assert event_text(['slip', ['egg1'], 2.0, 2.5]) == 'slip(egg1)@2.00-2.50'


def test_rpy_and_quaternions_round_trip():
    rpy = (0.1, -0.2, 0.3)
    assert rpy_of(quaternion_of_rpy(*rpy)) == pytest.approx(rpy)
    m = matrix_of((0, 0, 0), quaternion_of_rpy(0.0, 0.0, math.pi / 2))
    assert m[:3, 0] == pytest.approx([0.0, 1.0, 0.0])
