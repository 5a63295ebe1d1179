"""What is rejected before a simulation starts: scenarios, programs, parameters."""

from __future__ import annotations

import pytest

from projection_server import projection
from projection_server.simulation import Job, ProjectionError
from projection_server.simulation.scenario import parse_scenario


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
    assert job.params == {'force': 3.0, 'position': 0.0}


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


def test_parts_are_flattened_and_unknown_properties_ignored(make_scenario):
    scenario = parse_scenario(make_scenario(colour='white'))
    assert [e.name for e in scenario.entities] == [
        'kitchen_env', 'floor1', 'table1', 'pr2_robot', 'egg1']
    assert 'colour' not in scenario.entities[-1].properties
