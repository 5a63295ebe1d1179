"""Fixtures of the simulation tests: a grasping scenario and a small projection pool."""

from __future__ import annotations

import copy

import pybullet_data
import pytest

from projection_server.simulation import load_settings
from projection_server.workers.local import WorkerPool

# The grasping scenario of Kunze et al. (2011), sec. IV-A, in the form of docs/contracts.md.
# The egg's breaking force (10 N) puts the break between 9 and 11 N at the centre.
# Its friction is egg1's in the knowledge base (0.22): 1 N slips, 3 N holds.
GRASPING = {
    'name': 'grasping',
    'entities': [
        {'name': 'kitchen_env', 'class': 'environment',
         'pose': {'xyz': [0.0, 0.0, 0.0], 'rpy': [0.0, 0.0, 0.0]}, 'properties': {},
         'parts': [
             {'name': 'floor1', 'class': 'floor', 'properties': {'friction': 0.8}},
             {'name': 'table1', 'class': 'table',
              'pose': {'xyz': [0.0, 0.0, 0.72], 'rpy': [0.0, 0.0, 0.0]},
              'properties': {'shape': 'box', 'size_x': 1.2, 'size_y': 0.8, 'size_z': 0.04,
                             'height': 0.72, 'mass': 0.0, 'friction': 0.6,
                             'restitution': 0.1}},
         ]},
        {'name': 'pr2_robot', 'class': 'robot',
         'pose': {'xyz': [-0.6, 0.0, 0.0], 'rpy': [0.0, 0.0, 0.0]},
         'properties': {'gripper': 'pr2_gripper'}},
        {'name': 'egg1', 'class': 'egg',
         'pose': {'xyz': [0.0, 0.0, 0.742], 'rpy': [0.0, 0.0, 0.0]},
         'properties': {'shape': 'ellipsoid', 'length': 0.058, 'diameter': 0.044,
                        'mass': 0.06, 'friction': 0.22, 'restitution': 0.05,
                        'breaking_force': 10.0}},
    ],
}


# The Panda of pybullet_data as the knowledge base's panda_robot places it, by the table.
PANDA = {'name': 'panda_robot', 'class': 'robot', 'pose': {'xyz': [-0.68, 0.0, 0.72]},
         'properties': {'model': 'urdf',
                        'file': f'{pybullet_data.getDataPath()}/franka_panda/panda.urdf',
                        'tool_link': 'panda_hand', 'tool_offset': [0, 0, 0.1034],
                        'finger_joints': ['panda_finger_joint1', 'panda_finger_joint2'],
                        'max_force': 20.0, 'home': [0, -0.785, 0, -2.356, 0, 1.571, 0.785]}}


@pytest.fixture
def make_scenario():
    """``make_scenario(**egg_properties)``: the grasping scenario with changed egg properties."""
    def make(**egg):
        scenario = copy.deepcopy(GRASPING)
        scenario['entities'][-1]['properties'].update(egg)
        return scenario
    return make


@pytest.fixture(scope='module')
def pool(tmp_path_factory):
    """One worker, bags in a fresh directory; shared by the tests of a module."""
    with WorkerPool(tmp_path_factory.mktemp('bags'), workers=1) as shared:
        yield shared


@pytest.fixture
def refined_settings():
    """``refined_settings(factor[, program])``: the settings of a projection of ``program``
    whose query asks for a ``factor`` times finer time step (make_projection/5's physics
    option; control and logging keep their rates)."""
    def refine(factor, program='grasp_object'):
        settings = load_settings()
        return settings.for_projection(program, {'rate_hz': settings.physics.rate_hz * factor})
    return refine
