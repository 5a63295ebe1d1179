"""MuJoCo's compiled models shared by scenarios of one shape: a world whose scenario differs
from a compiled one only in numbers (an egg's friction, mass or breaking force, a table's
friction: a belief's worlds) gets a copy of that model with its own numbers, and that copy is
the model compiling its own scenario gives, bit for bit, and logs the same bag."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from projection_server.bags import typestore
from projection_server.simulation import Job, load_settings
from projection_server.simulation.engines.mujoco import world
from projection_server.simulation.runner import Simulator
from projection_server.simulation.scenario import parse_scenario

VARIED = [
    {'egg1': {'friction': 0.31}},
    {'egg1': {'mass': 0.067}},
    {'egg1': {'friction': 0.27, 'mass': 0.052, 'breaking_force': 8.5}},
    {'egg1': {'friction': 0.35}, 'table1': {'friction': 0.45}, 'floor1': {'friction': 0.3}},
]


def _scenario(make_scenario, changes):
    scenario = make_scenario()
    for entity in scenario['entities']:
        entity['properties'].update(changes.get(entity['name'], {}))
    return scenario


def _settings():
    return load_settings().for_projection('grasp_object', {'engine': 'mujoco'})


def _fields(model):
    """Every array of ``model`` and its option and statistic structs, as bytes."""
    out = {}
    for name in dir(model):
        if name.startswith('_'):
            continue
        value = getattr(model, name)
        if isinstance(value, np.ndarray):
            out[name] = (value.shape, value.tobytes())
    for struct in ('opt', 'stat'):
        part = getattr(model, struct)
        for name in dir(part):
            value = getattr(part, name)
            if not name.startswith('_') and not callable(value):
                out[f'{struct}.{name}'] = np.asarray(value).tobytes()
    return out


@pytest.mark.parametrize('changes', VARIED)
def test_a_model_given_another_scenarios_numbers_is_that_scenarios_compiled_model(
        make_scenario, changes):
    settings = _settings()
    nominal = parse_scenario(make_scenario())
    varied = parse_scenario(_scenario(make_scenario, changes))
    assert repr(world._shape(nominal)) == repr(world._shape(varied))
    template, _, spec = world._compile(nominal, settings, False)
    model = copy.copy(template)
    world._tune(model, mujoco.MjData(model), spec, varied)
    compiled = _fields(world._compile(varied, settings, False)[0])
    tuned = _fields(model)
    assert tuned.keys() == compiled.keys()
    assert [name for name in compiled if tuned[name] != compiled[name]] == []
    # The test can fail: the nominal model differs from the varied one where tuned.
    assert _fields(template) != compiled


def test_a_scenario_of_another_shape_is_compiled_on_its_own(make_scenario):
    nominal = parse_scenario(make_scenario())
    longer = parse_scenario(make_scenario(length=0.062))
    assert repr(world._shape(nominal)) != repr(world._shape(longer))


@pytest.mark.parametrize('params', [{'force': 5.0, 'position': 0.0},
                                    {'force': 9.0, 'position': 0.02}])
def test_a_projection_on_a_shared_model_logs_the_bag_of_its_own_compiled_model(
        make_scenario, tmp_path, params):
    def messages(path):
        with AnyReader([path], default_typestore=typestore()) as reader:
            return [(c.topic, t, raw) for c, t, raw in reader.messages()]

    settings = load_settings()
    nominal = Job.checked(make_scenario(), 'grasp_object', params, {'engine': 'mujoco'})
    varied = Job.checked(_scenario(make_scenario, VARIED[2]), 'grasp_object', params,
                         {'engine': 'mujoco'})
    simulator = Simulator()
    try:
        world._COMPILED.clear()
        simulator.run(nominal, settings, tmp_path / 'nominal')
        shared = simulator.run(varied, settings, tmp_path / 'shared')
        assert len(world._COMPILED) == 1   # the varied world took the nominal's model
        world._COMPILED.clear()
        own = simulator.run(varied, settings, tmp_path / 'own')
    finally:
        simulator.close()
    assert messages(tmp_path / 'shared') == messages(tmp_path / 'own')
    assert shared.monitor.records == own.monitor.records
    assert messages(tmp_path / 'shared') != messages(tmp_path / 'nominal')
