"""The world builder: every class of the contract becomes bodies with its properties."""

from __future__ import annotations

import pybullet
from pybullet_utils.bullet_client import BulletClient
import pytest

from projection_server.simulation import load_settings, ProjectionError
from projection_server.simulation.scenario import parse_scenario
from projection_server.simulation.world import build_world


@pytest.fixture
def client():
    bullet = BulletClient(connection_mode=pybullet.DIRECT)
    yield bullet
    bullet.disconnect()


def test_every_class_of_the_contract_is_built(client, make_scenario):
    scenario = make_scenario()
    scenario['entities'] += [
        {'name': 'cup1', 'class': 'cup', 'pose': {'xyz': [0.3, 0.2, 0.77]},
         'properties': {'diameter': 0.08, 'height': 0.1, 'mass': 0.2}},
        {'name': 'maker1', 'class': 'pancake_maker', 'pose': {'xyz': [-0.3, 0.2, 0.74]},
         'properties': {'diameter': 0.3, 'height': 0.04}},
        {'name': 'pancake1', 'class': 'pancake', 'pose': {'xyz': [-0.3, 0.2, 0.8]},
         'properties': {'diameter': 0.12, 'height': 0.01, 'mass': 0.05}},
        {'name': 'spatula1', 'class': 'spatula', 'pose': {'xyz': [0.3, -0.2, 0.73]},
         'properties': {'size_x': 0.25, 'size_y': 0.06, 'size_z': 0.01, 'mass': 0.1}},
        {'name': 'mix', 'class': 'particle_fluid', 'pose': {'xyz': [0.3, 0.2, 0.9]},
         'properties': {'count': 8, 'particle_radius': 0.005, 'particle_mass': 0.001}},
    ]
    physics = build_world(client, parse_scenario(scenario), load_settings())
    assert {'floor1', 'table1', 'pr2_robot', 'egg1', 'cup1', 'maker1', 'pancake1',
            'spatula1', 'mix_0', 'mix_7'} <= set(physics.bodies)
    assert physics.bodies['table1'].static and physics.bodies['maker1'].static
    assert not physics.bodies['egg1'].static
    assert 'pr2_robot' in physics.grippers


def test_object_properties_configure_the_simulator(client, make_scenario):
    physics = build_world(client, parse_scenario(make_scenario(friction=0.42, mass=0.07)),
                          load_settings())
    info = client.getDynamicsInfo(physics.body('egg1').body_id, -1)
    assert info[0] == pytest.approx(0.07)      # mass
    assert info[1] == pytest.approx(0.42)      # lateral friction
    top = client.getAABB(physics.body('table1').body_id)[1][2]
    assert top == pytest.approx(0.72, abs=0.005)


def test_the_egg_rests_on_the_table(client, make_scenario):
    physics = build_world(client, parse_scenario(make_scenario()), load_settings())
    for _ in range(120):
        physics.step()
    assert physics.contact_force('egg1', 'table1') == pytest.approx(0.06 * 9.81, rel=0.05)
    assert physics.object_load('egg1') == pytest.approx(0.06 * 9.81, rel=0.05)


def test_an_unknown_gripper_is_a_bad_scenario(client, make_scenario):
    scenario = make_scenario()
    scenario['entities'][1]['properties']['gripper'] = 'claw'
    with pytest.raises(ProjectionError) as info:
        build_world(client, parse_scenario(scenario), load_settings())
    assert info.value.kind == 'invalid_scenario'
