"""Properties a robot does not know exactly, through the real service: worlds drawn from a
scenario's beliefs, the probability of an outcome with its interval, and the errors."""

from __future__ import annotations

import json
import os

from projection_interfaces.srv import PrologQuery
import pytest

Q = PrologQuery.Request
SIM_TIMEOUT = 300.0
OK = '( \\+ occurs(break, _, TL), \\+ occurs(slip, _, TL) )'


def ask(call, text, timeout=SIM_TIMEOUT):
    r = call(PrologQuery, 'query', Q(mode=Q.ALL_SOLUTIONS, query=text, timeout=timeout,
                                     max_solutions=200), timeout=timeout * 2)
    return r, [json.loads(s) for s in r.solutions]


def solutions(call, text):
    r, sols = ask(call, text)
    assert r.ok, (r.error_kind, r.message)
    return sols


def probability(call, belief: str, forces, condition=OK, options='[samples(20), seed(1)]'):
    sols = solutions(call, f'''copy_scenario(grasping, S), {belief},
        outcome_probability(S, grasp_object, [(F, force, {forces})], {options}, TL,
                            {condition}, P)''')
    return {s['F']: dict(s['P']['dict']) for s in sols}   # P is a dict: JSON's dict form


def test_a_wider_friction_spread_lowers_the_probability_of_holding_at_the_slip_boundary(
        call):
    # 2 N holds an egg of friction from 0.156 (2 * 2 N * mu >= m (g + a) = 0.623 N): every
    # egg of the narrow belief; the wider spread puts about a fifth of its eggs below it.
    narrow = probability(call, 'scenario_set_property(S, egg1, friction, uniform(0.2, 0.4))',
                         [2])[2]
    wide = probability(call, 'scenario_set_property(S, egg1, friction, uniform(0.05, 0.55))',
                       [2])[2]
    assert wide['p'] < narrow['p'], (wide, narrow)


def test_a_weaker_shell_raises_the_probability_of_breaking_at_9_n(call):
    broken = '( occurs(break, _, TL) )'
    strong = probability(call, 'scenario_set_property(S, egg1, breaking_force, normal(10, 1))',
                         [9], broken)[9]
    weak = probability(call, 'scenario_set_property(S, egg1, breaking_force, normal(9, 1))',
                       [9], broken)[9]
    assert weak['p'] > strong['p'], (weak, strong)


def test_the_interval_contains_the_fraction_a_plain_grid_over_the_property_gives(call):
    sampled = probability(call, 'scenario_set_property(S, egg1, friction, uniform(0.2, 0.4))',
                          [1.5])[1.5]
    grid = solutions(call, f'''copy_scenario(grasping, S),
        member(Mu, [0.2, 0.21, 0.22, 0.23, 0.24, 0.25, 0.26, 0.27, 0.28, 0.29, 0.3,
                    0.31, 0.32, 0.33, 0.34, 0.35, 0.36, 0.37, 0.38, 0.39, 0.4]),
        copy_scenario(S, C), scenario_set_property(C, egg1, friction, Mu),
        make_projection(C, grasp_object, [(_, force, [1.5])], TL),
        ( {OK} -> Ok = 1 ; Ok = 0 )''')
    fraction = sum(s['Ok'] for s in grid) / len(grid)
    assert sampled['n'] == 20
    assert sampled['low'] <= fraction <= sampled['high'], (fraction, sampled)


def test_the_same_seed_draws_the_same_worlds_and_another_seed_others(call):
    query = '''copy_scenario(grasping, S),
        scenario_set_property(S, egg1, friction, uniform(0.2, 0.4)),
        scenario_set_property(S, egg1, breaking_force, normal(10, 1.5)),
        simulate(S, grasp_object, [(_, force, [5])], [samples(3), seed({seed})], Bag),
        translate(Bag, TL),
        quantity(sampled(egg1, friction), Mu, TL),
        quantity(sampled(egg1, breaking_force), B, TL)'''
    first = solutions(call, query.format(seed=7))
    again = solutions(call, query.format(seed=7))
    other = solutions(call, query.format(seed=8))
    draws = [(s['Mu'], s['B']) for s in first]
    assert draws == [(s['Mu'], s['B']) for s in again]
    assert len(set(draws)) == 3 and draws != [(s['Mu'], s['B']) for s in other]
    assert all(0.2 <= mu <= 0.4 for mu, _ in draws)
    # the bag's scenario is the world drawn: a plain world, no belief in it
    assert egg_in_bag(first[0]['Bag'])['friction'] == first[0]['Mu']


def egg_in_bag(bag):
    from projection_server.bags import read_records

    info = next(r.data for r in read_records(bag) if r.kind == 'info')
    (egg,) = [e for e in json.loads(info.scenario_json)['entities'] if e['name'] == 'egg1']
    return egg['properties']


def test_without_samples_the_nominal_world_is_projected(call):
    sols = solutions(call, '''copy_scenario(grasping, S),
        scenario_set_property(S, egg1, friction, normal(0.35, 0.05)),
        scenario_set_property(S, egg1, mass, uniform(0.05, 0.07)),
        simulate(S, grasp_object, [(_, force, [5])], [], Bag), translate(Bag, TL),
        ( quantity(sampled(egg1, _), _, TL) -> Sampled = 1 ; Sampled = 0 )''')
    assert not sols[0]['Sampled']
    egg = egg_in_bag(sols[0]['Bag'])
    assert egg['friction'] == 0.35 and egg['mass'] == pytest.approx(0.06)


def test_decide_stops_sampling_a_clearly_decided_parametrization(call):
    # 1 N holds an egg of friction from 0.307 (2 * 1 N * mu >= 0.623 N): none of these.
    decided = probability(call, 'scenario_set_property(S, egg1, friction, uniform(0.15, 0.29))',
                          [1, 5], options='[samples(30), seed(1), decide(0.9)]')
    assert decided[1]['n'] < 30 and decided[1]['high'] < 0.9, decided[1]   # slips: clear
    assert decided[5]['p'] == 1.0


@pytest.mark.parametrize('setup, goal, kind, words', [
    ('true', "[samples(0)]", 'domain_error', 'positive_integer'),
    ('true', "[samples(5), decide(1.5)]", 'domain_error', 'between 0 and 1'),
    ('true', "[samples(5), decide(0)]", 'domain_error', 'between 0 and 1'),
    ('scenario_set_property(S, egg1, friction, uniform(-2, -1))', '[samples(2)]',
     'domain_error', 'wholly outside'),
    ('scenario_set_property(S, egg1, restitution, normal(3, 0.1))', '[samples(2)]',
     'domain_error', 'wholly outside'),
    ('scenario_set_property(S, egg1, friction, normal(0.3, 0))', '[samples(2)]',
     'domain_error', 'SD must be above 0'),
    ('scenario_set_property(S, egg1, shape, uniform(0, 1))', '[samples(2)]',
     'type_error', ''),
])
def test_bad_beliefs_and_options_are_clear_errors(call, setup, goal, kind, words):
    r, _ = ask(call, f'''copy_scenario(grasping, S), {setup},
        outcome_probability(S, grasp_object, [(F, force, [5])], {goal}, TL, true, P)''',
        timeout=30.0)
    assert not r.ok and r.error_kind == kind, (r.error_kind, r.message)
    assert words in r.message, r.message
    r, sols = ask(call, 'X = 1')
    assert r.ok and sols == [{'X': 1}]


def test_a_dangerous_condition_is_refused_before_anything_runs(call):
    r, _ = ask(call, '''outcome_probability(grasping, grasp_object, [(F, force, [5])],
        [samples(2)], TL, shell('touch /tmp/projection_server_pwned'), P)''', timeout=30.0)
    assert not r.ok and r.error_kind == 'permission_error', (r.error_kind, r.message)
    assert not os.path.exists('/tmp/projection_server_pwned')


def test_table_i_for_an_egg_whose_friction_lies_between_0_15_and_0_29(call):
    # A belief centred on egg1's 0.22: 1 N holds from 0.307, 3 N from 0.104 (2 F mu >=
    # m (g + a) = 0.623 N), so 1 N slips on every egg of it and 5 N holds every one.
    sols = solutions(call, f'''copy_scenario(grasping, S),
        scenario_set_property(S, egg1, friction, uniform(0.15, 0.29)),
        outcome_probability(S, grasp_object, [(Pos, position, [-0.02, 0.00, 0.02]),
                                              (F, force, [1, 3, 5, 7, 9, 11])],
                            [samples(10), seed(2)], TL, {OK}, P)''')
    table = {(s['Pos'], s['F']): dict(s['P']['dict']) for s in sols}
    assert len(table) == 18 and all(p['n'] == 10 for p in table.values())
    for p in table.values():
        assert p['low'] <= p['p'] <= p['high']
    for pos in (-0.02, 0.0, 0.02):
        assert table[(pos, 1)]['p'] == 0.0      # slips on every egg
        assert table[(pos, 11)]['p'] == 0.0     # breaks every shell of 10 N
        assert table[(pos, 5)]['p'] == 1.0


def test_the_robust_grip_is_the_gentlest_force_proven_at_0_9(call):
    sols = solutions(call, f'''copy_scenario(grasping, S),
        scenario_set_property(S, egg1, friction, uniform(0.2, 0.4)),
        once(( outcome_probability(S, grasp_object, [(Pos, position, [0.0]),
                                                     (F, force, [1, 3, 5, 7, 9, 11])],
                                   [samples(35), seed(1), decide(0.9)], TL, {OK}, P),
               P.low >= 0.9 ))''')
    (robust,) = sols
    p = dict(robust['P']['dict'])
    assert robust['F'] in (3, 5) and p['n'] == 35 and p['low'] >= 0.9, robust


def test_a_plan_is_projected_over_a_belief_as_a_named_program_is(call):
    plan = '''plan([move_to(egg1, [-0.09, 0, 0], [orientation(side(0)), speed(2.0)]),
                   move_to(egg1, [0, 0, 0], [speed(0.15)]), close_gripper(F), wait(0.3),
                   move_by([0, 0, 0.1], [speed(0.1)]), wait(1.0)])'''
    sols = solutions(call, f'''copy_scenario(grasping, S),
        scenario_set_property(S, egg1, friction, uniform(0.2, 0.4)),
        outcome_probability(S, {plan}, [(F, force, [1, 5])], [samples(4), seed(1)], TL,
                            {OK}, P)''')
    assert {s['F']: dict(s['P']['dict'])['p'] for s in sols} == {1: 0.0, 5: 1.0}
