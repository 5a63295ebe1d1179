"""Object classes and robot models are registered units: the scenario checks and the world
builder read the registry, and another installed package can add its own."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from projection_server.simulation import objects, ProjectionError, robots
from projection_server.simulation.scenario import parse_scenario

PLUGIN = '''
"""An object class from another package: a kettle, a box of its own colour."""

from projection_server.simulation.objects import ObjectClass, Property, register
from projection_server.simulation.objects.common import primitive
from projection_server.simulation.objects.registry import POSITIVE, REQUIRED


def build(physics, entity):
    p = entity.properties
    primitive(physics, entity, 'box', (p['size'],) * 3, (0.2, 0.2, 0.8, 1.0))


register(ObjectClass(
    name='kettle',
    properties=(Property('size', REQUIRED, POSITIVE, 'm'), Property('mass', 1.0, POSITIVE),
                Property('friction', 0.5, POSITIVE), Property('restitution', 0.1, POSITIVE)),
    build=build))
'''

USE = '''
import json
import pybullet

from projection_server.simulation import load_settings, objects
from projection_server.simulation.physics import bound_client
from projection_server.simulation.scenario import parse_scenario
from projection_server.simulation.world import build_world

scenario = parse_scenario({'name': 's', 'entities': [
    {'name': 'k1', 'class': 'kettle', 'pose': {'xyz': [0, 0, 0.5]},
     'properties': {'size': 0.2}}]})
client = bound_client(pybullet.DIRECT)
physics = build_world(client, scenario, load_settings())
print(json.dumps({'classes': objects.names(),
                  'position': client.getBasePositionAndOrientation(physics.body('k1').body_id)[0],
                  'mass': client.getDynamicsInfo(physics.body('k1').body_id, -1)[0]}))
'''


def test_a_package_adds_an_object_class_through_its_entry_point(tmp_path):
    (tmp_path / 'kettle_plugin.py').write_text(PLUGIN)
    info = tmp_path / 'kettle_plugin-0.1.dist-info'
    info.mkdir()
    (info / 'METADATA').write_text('Metadata-Version: 2.1\nName: kettle-plugin\nVersion: 0.1\n')
    (info / 'entry_points.txt').write_text(
        '[projection_server.objects]\nkettle = kettle_plugin\n')
    env = {**os.environ,
           'PYTHONPATH': os.pathsep.join([str(tmp_path), os.environ.get('PYTHONPATH', '')])}
    out = subprocess.run([sys.executable, '-c', textwrap.dedent(USE)], env=env, check=True,
                         capture_output=True, text=True, timeout=120).stdout
    import json

    result = json.loads(out.strip().splitlines()[-1])
    assert 'kettle' in result['classes'] and 'egg' in result['classes']
    assert result['position'] == pytest.approx([0.0, 0.0, 0.5])
    assert result['mass'] == 1.0


def test_without_the_plugin_the_class_is_unknown():
    with pytest.raises(ProjectionError) as info:
        parse_scenario({'name': 's', 'entities': [{'name': 'k1', 'class': 'kettle'}]})
    assert info.value.kind == 'invalid_scenario'
    assert 'unknown class' in info.value.message and 'egg' in info.value.message


def test_a_class_name_is_registered_once():
    with pytest.raises(ValueError):
        objects.register(objects.get('egg'))


def test_every_class_is_built_by_its_unit_or_by_its_owner():
    owned = {'gripper'}   # built by the robot's model
    for name in objects.names():
        unit = objects.get(name)
        assert (unit.build is None) == (name in owned), name
        assert unit.describe()['class'] == name


def test_a_robot_of_an_unknown_model_is_refused_before_a_world_is_built():
    with pytest.raises(ProjectionError) as info:
        parse_scenario({'name': 's', 'entities': [
            {'name': 'r', 'class': 'robot', 'properties': {'model': 'hal9000'}}]})
    assert info.value.kind == 'invalid_scenario'
    assert 'hal9000' in info.value.message and 'pr2' in info.value.message
    assert 'pr2' in robots.names()
