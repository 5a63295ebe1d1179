"""Revolute fingers push with the force a plan asks for: the xArm6's linkage and the KUKA's
WSG50 squeeze the egg on the table with close_gripper(F), each pad's contact force about F;
the opening the gripper reports is the gap between its pads; a grasp run twice is the
same."""

from __future__ import annotations

import pybullet
import pybullet_data
import pytest

from projection_server.bags import BagWriter
from projection_server.simulation import load_settings
from projection_server.simulation.job import Job
from projection_server.simulation.physics import bound_client
from projection_server.simulation.runner import Projection

DATA = pybullet_data.getDataPath()
ROBOTS = {
    'xarm': ({'file': f'{DATA}/xarm/xarm6_with_gripper.urdf',
              'tool_link': 'xarm_gripper_base_link', 'tool_offset': [0, 0, 0.154],
              'finger_joints': ['drive_joint'], 'pad_links': ['left_finger', 'right_finger'],
              'max_force': 30},
             [-0.68, 0, 0.72], 0.01),
    'kuka': ({'file': f'{DATA}/kuka_iiwa/kuka_with_gripper2.sdf',
              'tool_link': 'lbr_iiwa_link_7', 'tool_offset': [0, 0.022, 0.276],
              'tool_rpy': [0, 0, 1.5708],
              'finger_joints': ['base_left_finger_joint', 'base_right_finger_joint'],
              'finger_open': [-0.3, 0.3], 'finger_closed': [0, 0], 'max_force': 30,
              'home': [0, 0.41, 0, -1.59, 0, 1.14, 0]},
             [-0.8, 0, 0.72], 0.0),
}


def squeeze(scenario, robot, force, tmp_path):
    """The pads' contact forces on the egg [N] and the gripper's (opening, force) after
    ``robot`` has closed on the egg of the grasping ``scenario`` with ``force`` and waited."""
    properties, xyz, height = ROBOTS[robot]
    scenario['entities'][1] = {'name': 'arm1', 'class': 'robot', 'pose': {'xyz': xyz},
                               'properties': {'model': 'urdf', **properties}}
    scenario['entities'][2]['pose']['xyz'] = [-0.3, 0.0, 0.742]
    plan = [{'action': 'move_to', 'object': 'egg1', 'offset': [0, 0, 0.1],
             'orientation': ['top', 0.0], 'speed': 0.5},
            {'action': 'move_to', 'object': 'egg1', 'offset': [0, 0, height], 'speed': 0.1},
            {'action': 'close_gripper', 'force': force}, {'action': 'wait', 'seconds': 0.3}]
    client = bound_client(pybullet.DIRECT)
    try:
        with BagWriter(tmp_path / 'bag') as bag:
            projection = Projection(client, Job.checked(scenario, 'plan', {}, None, plan),
                                    load_settings(), bag)
            physics = projection.physics
            while projection.task.index < 3:
                projection.advance(physics.step_count + 24)
            projection.advance(physics.step_count + 48)
            arm = physics.bodies['arm1'].body_id
            forces = {}
            for point in client.getContactPoints(physics.bodies['egg1'].body_id, arm):
                link = physics.link_name(arm, point[4])
                forces[link] = forces.get(link, 0.0) + point[9]
            return forces, physics.grippers['arm1'].state()
    finally:
        client.disconnect()


@pytest.mark.parametrize('robot, pads', [('xarm', {'left_finger', 'right_finger'}),
                                         ('kuka', {'left_finger_tip', 'right_finger_tip'})])
def test_each_pad_pushes_with_about_the_force_asked_for(robot, pads, make_scenario, tmp_path):
    forces, (opening, measured) = squeeze(make_scenario(), robot, 3.0, tmp_path)
    assert set(forces) == pads, forces
    assert all(2.6 <= f <= 3.3 for f in forces.values()), forces
    assert measured == pytest.approx(3.0, rel=0.01)
    assert opening == pytest.approx(0.044, abs=0.004)   # the egg's diameter


def test_a_linkage_grasp_is_the_same_run_twice(make_scenario, tmp_path):
    first = squeeze(make_scenario(), 'xarm', 5.0, tmp_path / 'a')
    assert squeeze(make_scenario(), 'xarm', 5.0, tmp_path / 'b') == first
