"""What is rejected before a simulation starts: scenarios, programs, parameters."""

from __future__ import annotations

import json
from pathlib import Path
import subprocess

import pytest

from projection_server import projection
from projection_server.simulation import Job, ProjectionError
from projection_server.simulation import objects
from projection_server.simulation.scenario import accepted_properties, parse_scenario


def kind_of(call, *args):
    with pytest.raises(ProjectionError) as info:
        call(*args)
    return info.value.kind


def test_programs_list_their_formal_parameters():
    (grasp,) = [p for p in projection.programs() if p['program'] == 'grasp_object']
    params = {p['name']: p for p in grasp['params']}
    assert params['force']['unit'] == 'N'
    assert params['position']['unit'] == 'm'
    assert params['position']['min'] < 0.0 < params['position']['max']


def test_unknown_program(make_scenario):
    assert kind_of(Job.checked, make_scenario(), 'juggle', {}) == 'unknown_program'


def test_parameter_out_of_range(make_scenario):
    assert kind_of(Job.checked, make_scenario(), 'grasp_object',
                   {'force': 500.0}) == 'invalid_parameters'


def test_unknown_parameter(make_scenario):
    assert kind_of(Job.checked, make_scenario(), 'grasp_object',
                   {'speed': 1.0}) == 'invalid_parameters'


def test_parameter_that_is_not_a_number(make_scenario):
    assert kind_of(Job.checked, make_scenario(), 'grasp_object',
                   {'force': 'hard'}) == 'invalid_parameters'


def test_missing_parameters_take_their_defaults(make_scenario):
    job = Job.checked(make_scenario(), 'grasp_object', {'force': 3})
    assert job.params == {'force': 3.0, 'position': 0.0, 'lift_time': 1.0}


def test_unknown_class_is_a_bad_scenario(make_scenario):
    scenario = make_scenario()
    scenario['entities'].append({'name': 'dragon1', 'class': 'dragon'})
    assert kind_of(parse_scenario, scenario) == 'invalid_scenario'


def test_missing_required_property_is_a_bad_scenario(make_scenario):
    scenario = make_scenario()
    del scenario['entities'][-1]['properties']['mass']
    assert kind_of(parse_scenario, scenario) == 'invalid_scenario'


def test_negative_size_is_a_bad_scenario(make_scenario):
    assert kind_of(parse_scenario, make_scenario(length=-0.05)) == 'invalid_scenario'


def test_duplicate_names_are_a_bad_scenario(make_scenario):
    scenario = make_scenario()
    scenario['entities'].append(dict(scenario['entities'][-1]))
    assert kind_of(parse_scenario, scenario) == 'invalid_scenario'


def test_parts_are_flattened(make_scenario):
    scenario = parse_scenario(make_scenario())
    assert [e.name for e in scenario.entities] == [
        'kitchen_env', 'floor1', 'table1', 'pr2_robot', 'egg1']


def test_a_property_the_simulator_does_not_honour_is_refused_by_name(make_scenario):
    with pytest.raises(ProjectionError) as info:
        parse_scenario(make_scenario(colour='white'))
    assert info.value.kind == 'invalid_scenario'
    assert "egg1: egg has no property 'colour'" in str(info.value)
    assert 'accepted: ' + ', '.join(accepted_properties('egg')) in str(info.value)


def test_a_descriptive_property_must_say_what_the_simulator_builds(make_scenario):
    assert kind_of(parse_scenario, make_scenario(shape='box')) == 'invalid_scenario'
    assert parse_scenario(make_scenario(shape='ellipsoid')).entities[-1].name == 'egg1'


def kb(goal):
    """The JSON that a Prolog goal writes (with the knowledge base loaded)."""
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run(
        ['swipl', '-q', '-g', 'use_module(library(http/json))',
         '-g', 'use_module(prolog/knowledge_base)', '-g', 'use_module(prolog/scenario)',
         '-g', f'knowledge_base_load, {goal}, halt'],
        cwd=root, check=True, capture_output=True, text=True, timeout=60).stdout
    return json.loads(out)


def test_the_knowledge_bases_simulator_classes_are_the_registered_object_classes():
    classes = kb('findall(S, (kb_class(C), catch(kb_simulator_class(C, S), '
                 'error(domain_error(_, _), _), fail)), Ss), sort(Ss, Sorted), '
                 'json_write(current_output, Sorted)')
    assert classes == objects.names()


def test_the_knowledge_base_offers_exactly_the_properties_the_simulator_honours():
    offered = kb('findall(C-K, (member(C, ' + json.dumps(objects.names()).replace('"', '')
                 + '), kb_class_properties(C, K)), Ps), dict_pairs(D, c, Ps), '
                 'json_write_dict(current_output, D)')
    for cls in objects.names():
        aliases = set(objects.get(cls).aliases)
        honoured = set(accepted_properties(cls))
        assert set(offered[cls]) <= honoured | aliases, cls
        # The factory's particle pancake and a batter's handed-on state are given by lists
        # (of points, index pairs, temperatures), not KB values.
        assert honoured - set(offered[cls]) <= {'particles', 'joints', 'positions',
                                                'temperatures', 'bonds'}, cls


def test_class_defaults_and_factory_objects_use_only_honoured_properties():
    classes = json.dumps(objects.names()).replace('"', '')
    defaults = kb(f'findall(C-D, (member(C, {classes}), kb_class_defaults(C, D)), Ps), '
                  'dict_pairs(J, c, Ps), json_write_dict(current_output, J)')
    for cls, values in defaults.items():
        assert set(values) <= set(accepted_properties(cls)), cls
    pancake = kb('use_module(prolog/object_factory), object_model(pancake, _{name: p, '
                 'particles: [[0.0, 0.0, 0.75], [0.01, 0.0, 0.75], [0.0, 0.01, 0.75]]}, E), '
                 'json_write_dict(current_output, _{name: s, entities: [E]})')
    parse_scenario(pancake)


@pytest.mark.parametrize('name', ['grasping', 'pouring', 'turning'])
def test_the_knowledge_bases_scenarios_use_only_honoured_properties(name):
    parse_scenario(kb(f'scenario_description({name}, D), json_write_dict(current_output, D)'))
