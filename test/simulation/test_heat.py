"""Heat in a batter (projection_server.simulation.batter.heat): a small batter on a hot pan
warms, sets and bonds, its state is logged and read back, and the set/no-set outcome is
the same at a 2x finer time step."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from projection_server.simulation import load_settings
from projection_server.simulation.job import Job
from projection_server.workers.run import run_projection, translate_bag

RADIUS = 0.0048
TOP = 0.75          # the pancake maker's top

# A hexagonal layer of 37 batter particles resting on the middle of a heated pancake maker.
LAYER = [[RADIUS * (2 * i + j), RADIUS * math.sqrt(3) * j, TOP + RADIUS]
         for j in range(-3, 4) for i in range(-3, 4) if abs(i + j) <= 3 and abs(i) <= 3]
BATTER = {'particle_count': len(LAYER), 'particle_radius': RADIUS, 'particle_mass': 0.0005,
          'friction': 0.35, 'restitution': 0.0, 'rolling_friction': 0.02,
          'spinning_friction': 0.02, 'damping': 30.0, 'positions': LAYER,
          'temperature': 20.0, 'setting_temperature': 70.0, 'pan_heat_rate': 0.5,
          'conduction_rate': 2.0, 'bond_strength': 2.0}
SCENARIO = {
    'name': 'cooking',
    'entities': [
        {'name': 'table1', 'class': 'table', 'pose': {'xyz': [0.0, 0.0, 0.70]},
         'properties': {'size_x': 1.2, 'size_y': 0.8, 'size_z': 0.04, 'height': 0.72,
                        'mass': 0.0, 'friction': 0.6}},
        {'name': 'pancake_maker1', 'class': 'pancake_maker', 'pose': {'xyz': [0.0, 0.0, 0.735]},
         'properties': {'radius': 0.15, 'height': 0.03, 'friction': 0.7,
                        'temperature': 195.0, 'heating': 1}},
        {'name': 'batter1', 'class': 'particle_fluid', 'properties': BATTER},
    ],
}


def cooking(duration=1.5, rate_hz=None, **changes):
    scenario = copy.deepcopy(SCENARIO)
    for key, value in changes.items():
        entity = scenario['entities'][1 if key in ('heating',) else 2]
        entity['properties'][key] = value
    physics = {'rate_hz': rate_hz} if rate_hz else {}
    return Job.checked(scenario, 'wait', {'duration': duration}, physics)


def quantities(timeline):
    return {(name, tuple(args)): value for name, args, value in timeline['quantities']}


def test_batter_on_a_hot_pan_sets_bonds_and_its_bag_gives_the_same_timeline(tmp_path):
    timeline = run_projection(cooking(), load_settings(), tmp_path / 'cook')
    q = quantities(timeline)
    assert q[('set_fraction', ('batter1',))] == 1.0
    assert 70.0 < q[('temperature', ('batter1',))] < 195.0
    assert len(q[('bonds', ('batter1',))]) > len(LAYER)   # a triangulated net
    assert ['set', ['batter1']] in [e[:2] for e in timeline['events']]
    assert ['set', ['batter1']] in [f[:2] for f in timeline['fluents']]
    assert 'upside_down' not in [f[0] for f in timeline['fluents']]
    # The batter on the pan, in the order of its positions: here all of it.
    assert q[('particles_on_temperatures', ('pancake_maker1',))] == q[
        ('particle_temperatures', ('batter1',))]
    assert q[('particles_on_bonds', ('pancake_maker1',))] == q[('bonds', ('batter1',))]
    assert translate_bag(tmp_path / 'cook') == timeline
    from rosbags.highlevel import AnyReader

    from projection_server.bags import typestore
    store, topics = typestore(), {}
    with AnyReader([tmp_path / 'cook'], default_typestore=store) as reader:
        for connection, _, raw in reader.messages():
            if connection.topic in ('/projection/batter', '/projection/bonds'):
                message = reader.deserialize(raw, connection.msgtype)
                assert bytes(raw) == bytes(store.serialize_cdr(message, connection.msgtype))
                topics[connection.topic] = topics.get(connection.topic, 0) + 1
    assert topics['/projection/batter'] == timeline['meta']['samples']
    assert 1 < topics['/projection/bonds'] < topics['/projection/batter']   # on change


def test_a_pan_switched_off_sets_nothing(tmp_path):
    q = quantities(run_projection(cooking(heating=0), load_settings(), tmp_path / 'off'))
    assert q[('set_fraction', ('batter1',))] == 0.0
    assert q[('temperature', ('batter1',))] == pytest.approx(20.0)
    assert q[('bonds', ('batter1',))] == []


@pytest.mark.parametrize('duration, outcome', [(0.4, False), (1.5, True)])
def test_setting_is_the_same_at_a_2x_finer_step(tmp_path, duration, outcome):
    """A particle on the pan reaches 70 deg C after ln(175/125) / 0.5 = 0.67 s; the layer
    is set (half of it) by then, at either step."""
    settings = load_settings()
    for rate in (240, 480):
        timeline = run_projection(cooking(duration, rate), settings, tmp_path / f'c{rate}')
        q = quantities(timeline)
        assert (q[('set_fraction', ('batter1',))] >= 0.5) is outcome, rate
        assert ('set' in [e[0] for e in timeline['events']]) is outcome, rate


def test_the_temperature_follows_newtons_law_exactly_over_a_step():
    """A particle on the pan alone, at either step: T(t) = 195 - 175 exp(-0.5 t)."""
    from projection_server.simulation.world import build_world
    from projection_server.simulation.physics import bound_client
    from projection_server.simulation.scenario import parse_scenario
    import pybullet

    client = bound_client(pybullet.DIRECT)
    try:
        scenario = copy.deepcopy(SCENARIO)
        batter = scenario['entities'][2]['properties']
        batter.update(particle_count=1, positions=[[0.0, 0.0, TOP + RADIUS]])
        for rate in (240, 960):
            settings = load_settings().for_projection('wait', {'rate_hz': rate})
            physics = build_world(client, parse_scenario(scenario), settings)
            for _ in range(rate):
                physics.step()
            heat = physics.step_hooks[-1]
            assert heat.temperature[0] == pytest.approx(195 - 175 * np.exp(-0.5), abs=1e-6)
    finally:
        client.disconnect()


def test_the_emerged_pancake_is_the_largest_bonded_cluster_and_its_turn_is_kabschs():
    from projection_server.timeline import cooking

    assert cooking.largest_cluster(np.array([[0, 1], [1, 2], [3, 4]]), 6).tolist() == [0, 1, 2]
    assert cooking.largest_cluster(np.zeros((0, 2)), 4).tolist() == []
    flat = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [0.01, 0.01, 0.002]])
    turned = flat @ np.diag([1.0, -1.0, -1.0]).T + [0.05, 0.0, 0.1]   # half a turn about x
    assert cooking.upside_down(cooking.rotation(flat, turned))
    assert not cooking.upside_down(cooking.rotation(flat, flat + 0.3))
