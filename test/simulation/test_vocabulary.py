"""The vocabulary of a scenario's timelines: what the translation's rules may name, and the
check that holds every timeline to it (a rule that emits an undeclared name fails)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from projection_server.errors import ProjectionError
from projection_server.simulation.scenario import parse_scenario
from projection_server.projection import vocabulary as description_vocabulary
from projection_server.timeline.vocabulary import check, vocabulary

from .conftest import GRASPING

POURING = yaml.safe_load((Path(__file__).parent / 'pouring.yaml').read_text())


def names(vocab, kind):
    return {name for name, _ in vocab[kind]}


def test_a_grasps_objects_are_its_entities_and_their_parts():
    assert vocabulary(parse_scenario(GRASPING))['objects'] == [
        'egg1', 'floor1', 'kitchen_env', 'pr2_robot', 'table1']


def test_a_pours_vocabulary_has_the_particle_quantities_and_a_grasps_has_not():
    pour, grasp = vocabulary(parse_scenario(POURING)), vocabulary(parse_scenario(GRASPING))
    assert {'particles_on', 'particles_spilled', 'temperature'} <= names(pour, 'quantities')
    assert 'spill' in names(pour, 'events')
    assert not {'particles_on', 'particles_spilled'} & names(grasp, 'quantities')
    assert 'spill' not in names(grasp, 'events')


def test_a_description_with_beliefs_has_the_vocabulary_of_its_nominal_world():
    belief = {'distribution': 'uniform', 'low': 0.2, 'high': 0.4}
    described = {**GRASPING, 'entities': [*GRASPING['entities'][:-1], {
        **GRASPING['entities'][-1],
        'properties': {**GRASPING['entities'][-1]['properties'], 'friction': belief}}]}
    assert description_vocabulary(described) == vocabulary(parse_scenario(GRASPING))


def test_a_timeline_within_its_vocabulary_passes():
    vocab = vocabulary(parse_scenario(GRASPING))
    check({'fluents': [['contact', ['egg1', 'pr2_robot'], 0.0, 1.0]],
           'events': [['break', ['egg1'], 1.0, 1.0]],
           'quantities': [['sampled', ['egg1', 'friction'], 0.3]]}, vocab)


@pytest.mark.parametrize('timeline', [
    {'events': [['brake', ['egg1'], 1.0, 1.0]]},                  # a name it lacks
    {'events': [['break', ['egg1', 'table1'], 1.0, 1.0]]},        # another arity
    {'fluents': [['in_gripper', ['egg2'], 0.0, 1.0]]},            # an object it lacks
    {'quantities': [['particles_on', ['table1'], 3]]},            # a pour's, not a grasp's
], ids=['name', 'arity', 'object', 'fluid_quantity'])
def test_a_term_outside_the_vocabulary_fails_the_timeline(timeline):
    with pytest.raises(ProjectionError, match='does not declare'):
        check(timeline, vocabulary(parse_scenario(GRASPING)))
