"""A node whose ``physics_engine`` parameter is MuJoCo, through the real service: a query
that names no engine projects on MuJoCo at MuJoCo's own settings, its defaults are
MuJoCo's, and a query that names PyBullet still gets PyBullet's."""

from __future__ import annotations

import json
from pathlib import Path

from projection_interfaces.srv import PrologQuery
import pytest

from test.nodes import caller, own_server

Q = PrologQuery.Request
TIMEOUT = 120.0


@pytest.fixture(scope='module')
def call(rclpy_context, tmp_path_factory, node):
    params = {'physics_engine': 'mujoco',
              'bag_dir': str(tmp_path_factory.mktemp('default_engine_bags'))}
    with own_server('default_engine_server', params, tmp_path_factory) as name:
        with caller(name, node) as c:
            yield c


def ask(call, text):
    r = call(PrologQuery, 'query', Q(mode=Q.ONCE, query=text, timeout=TIMEOUT),
             timeout=TIMEOUT * 2)
    assert r.ok, (r.error_kind, r.message)
    return json.loads(r.solutions[0])


def recorded(bag: str) -> dict:
    """The settings a bag's ``/projection/info`` recorded."""
    from rosbags.highlevel import AnyReader

    from projection_server.bags import typestore
    with AnyReader([Path(bag)], default_typestore=typestore()) as reader:
        connections = [c for c in reader.connections if c.topic == '/projection/info']
        for connection, _, raw in reader.messages(connections):
            return json.loads(reader.deserialize(raw, connection.msgtype).settings_json)
    raise AssertionError(f'{bag}: no /projection/info')


def test_a_query_naming_no_engine_runs_on_the_nodes_engine_at_its_own_step(call):
    s = ask(call, '''simulate(grasping, grasp_object, [(_, force, [5])], [], Bag),
                     projection_physics_setting(grasp_object, rate_hz, S),
                     get_dict(default, S, Rate),
                     projection_physics_setting(grasp_object, engine, E),
                     get_dict(default, E, Engine)''')
    assert (s['Rate'], s['Engine']) == (120, 'mujoco')
    physics = recorded(s['Bag'])['physics']
    assert (physics['engine'], physics['rate_hz']) == ('mujoco', 120)


def test_a_query_naming_pybullet_gets_pybullets_settings(call):
    s = ask(call, '''simulate(grasping, grasp_object, [(_, force, [5])],
                              [physics(_{engine: pybullet})], Bag)''')
    physics = recorded(s['Bag'])['physics']
    assert 'engine' not in physics and physics['rate_hz'] == 240   # PyBullet's, as ever
