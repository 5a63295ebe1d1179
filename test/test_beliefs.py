"""The worlds drawn from a scenario's beliefs (projection_server.beliefs), without ROS."""

from __future__ import annotations

import statistics

import pytest

from projection_server import beliefs


def egg(**properties):
    return {'name': 'egg_s', 'entities': [
        {'name': 'egg1', 'class': 'egg', 'properties': {'mass': 0.06, **properties}},
        {'name': 'egg2', 'class': 'egg', 'properties': {'friction': 0.3}}]}


UNIFORM = {'distribution': 'uniform', 'low': 0.2, 'high': 0.4}


def test_a_world_is_its_seed_and_index_and_nothing_else():
    scenario = egg(friction=UNIFORM,
                   breaking_force={'distribution': 'normal', 'mean': 10, 'sd': 1.5})
    first, drawn = beliefs.world(scenario, 7, 3)
    assert beliefs.world(scenario, 7, 3) == (first, drawn)
    assert [(e, k) for e, k, _ in drawn] == [('egg1', 'breaking_force'), ('egg1', 'friction')]
    assert beliefs.world(scenario, 7, 4)[1] != drawn
    assert beliefs.world(scenario, 8, 3)[1] != drawn
    assert not beliefs.has_beliefs(first) and beliefs.has_beliefs(scenario)
    assert scenario['entities'][0]['properties']['friction'] == UNIFORM   # not changed


def test_draws_follow_their_distribution_within_the_property_range():
    uniform = [beliefs.world(egg(friction=UNIFORM), 1, i)[1][0][2] for i in range(2000)]
    assert min(uniform) >= 0.2 and max(uniform) <= 0.4
    assert statistics.mean(uniform) == pytest.approx(0.3, abs=0.005)
    # a friction cannot be negative: normal(0.02, 0.05) is cut at 0, not clipped to a lump
    normal = [beliefs.world(egg(friction={'distribution': 'normal', 'mean': 0.02, 'sd': 0.05}),
                            1, i)[1][0][2] for i in range(2000)]
    assert min(normal) >= 0.0 and sum(v == 0.0 for v in normal) == 0
    assert statistics.median(normal) == pytest.approx(0.0423, abs=0.004)
    choice = [beliefs.world(egg(friction={'distribution': 'choice', 'values': [0.1, 0.5]}),
                            1, i)[1][0][2] for i in range(400)]
    assert set(choice) == {0.1, 0.5} and 150 < choice.count(0.1) < 250


def test_the_nominal_world_is_the_middle_the_mean_within_range():
    nominal = beliefs.nominal(egg(
        friction=UNIFORM, restitution={'distribution': 'normal', 'mean': 1.2, 'sd': 0.5},
        breaking_force={'distribution': 'choice', 'values': [8, 12]}))
    props = nominal['entities'][0]['properties']
    assert props == {'mass': 0.06, 'friction': pytest.approx(0.3), 'restitution': 1.0,
                     'breaking_force': 10.0}
    plain = egg(friction=0.3)
    assert beliefs.nominal(plain) is plain


@pytest.mark.parametrize('key, belief, words', [
    ('friction', {'distribution': 'uniform', 'low': 0.4, 'high': 0.2}, 'low end must be below'),
    ('friction', {'distribution': 'uniform', 'low': -2, 'high': -1}, 'wholly outside'),
    ('friction', {'distribution': 'normal', 'mean': 0.3, 'sd': 0}, 'SD must be above 0'),
    ('restitution', {'distribution': 'normal', 'mean': 30, 'sd': 1}, 'wholly outside'),
    ('friction', {'distribution': 'normal', 'mean': 'a', 'sd': 1}, 'finite number'),
    ('friction', {'distribution': 'choice', 'values': []}, 'non-empty list'),
    ('friction', {'distribution': 'choice', 'values': [0.1, -1]}, 'outside'),
    ('friction', {'distribution': 'beta', 'a': 1}, 'unknown distribution'),
    ('shape', UNIFORM, 'no numeric property'),
])
def test_a_bad_belief_says_what_is_wrong(key, belief, words):
    assert words in beliefs.problem('egg', key, belief)
    assert beliefs.problem('egg', 'friction', UNIFORM) is None
