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


def test_the_environments_gravity_is_the_worlds(client, make_scenario):
    scenario = make_scenario()
    scenario['entities'][0]['properties']['gravity'] = 3.0
    physics = build_world(client, parse_scenario(scenario), load_settings())
    for _ in range(120):
        physics.step()
    assert physics.contact_force('egg1', 'table1') == pytest.approx(0.06 * 3.0, rel=0.05)


def rolled_distance(client, make_scenario, **egg):
    """How far an egg rolls on the table in 1 s, set rolling about its long axis."""
    physics = build_world(client, parse_scenario(make_scenario(**egg)), load_settings())
    body = physics.body('egg1').body_id
    for _ in range(60):
        physics.step()
    start = client.getBasePositionAndOrientation(body)[0]
    client.resetBaseVelocity(body, (0.0, 0.3, 0.0), (-0.3 / 0.022, 0.0, 0.0))
    for _ in range(240):
        physics.step()
    end = client.getBasePositionAndOrientation(body)[0]
    return abs(end[1] - start[1]), client.getDynamicsInfo(body, -1)


def test_rolling_friction_slows_a_rolling_egg(client, make_scenario):
    free, info = rolled_distance(client, make_scenario, rolling_friction=0.0)
    braked, info = rolled_distance(client, make_scenario, rolling_friction=0.004)
    assert info[6] == pytest.approx(0.004)
    assert free > 0.15 and braked < 0.5 * free


def spun_angle(client, make_scenario, **egg):
    """The angle [rad] an egg lying on the table turns in 0.5 s, spun about the vertical."""
    physics = build_world(client, parse_scenario(make_scenario(**egg)), load_settings())
    body = physics.body('egg1').body_id
    for _ in range(60):
        physics.step()
    client.resetBaseVelocity(body, (0.0, 0.0, 0.0), (0.0, 0.0, 6.0))
    yaw = 0.0
    for _ in range(120):
        physics.step()
        yaw += client.getBaseVelocity(body)[1][2] / 240
    return yaw, client.getDynamicsInfo(body, -1)


def test_spinning_friction_stops_a_spinning_egg(client, make_scenario):
    free, _ = spun_angle(client, make_scenario, spinning_friction=0.0)
    braked, info = spun_angle(client, make_scenario, spinning_friction=0.01)
    assert info[7] == pytest.approx(0.01)
    assert free > 1.5 and braked < 0.5 * free


def test_an_egg_given_on_the_table_starts_clear_of_it(client, make_scenario):
    physics = build_world(client, parse_scenario(make_scenario()), load_settings())
    egg, table = physics.body('egg1').body_id, physics.body('table1').body_id
    assert min(p[8] for p in client.getClosestPoints(egg, table, 0.01)) >= 0.0


def test_the_remains_of_a_broken_egg_lie_where_the_egg_lay(client, make_scenario):
    physics = build_world(client, parse_scenario(make_scenario()), load_settings())
    for _ in range(60):
        physics.step()
    egg = physics.body('egg1').body_id
    bottom = client.getAABB(egg)[0][2]
    (shell,) = physics.models
    shell.broken = True
    shell._replace(physics, 'egg1')
    remains = physics.body('egg1').body_id
    assert remains != egg
    assert client.getAABB(remains)[0][2] == pytest.approx(bottom, abs=0.002)
    start = client.getBasePositionAndOrientation(remains)[0][2]
    for _ in range(60):
        physics.step()
    assert client.getBasePositionAndOrientation(remains)[0][2] == pytest.approx(start, abs=0.002)
    assert physics.contact_force('egg1', 'table1') == pytest.approx(0.06 * 9.81, rel=0.1)
