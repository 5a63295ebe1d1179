"""Cheap versions of the paper's experiments (section IV) through the live query service.

Each is one query of the paper's kind: counterfactual eggs made with ``copy_scenario`` and
``scenario_set_property`` (IV-A), two points of the pouring grid (IV-B, Table II), the
turning query in Table III's form (IV-C), and determinism of a projection's timeline.
The forces below were found by asking the service; the tests assert directions only
(variant vs. the knowledge base's egg at the same force).
"""

from __future__ import annotations

import json
import math

from projection_interfaces.srv import PrologQuery
import pytest

Q = PrologQuery.Request
TIMEOUT = 900.0  # seconds per request: four pours of a loaded machine
OUTCOME = '( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip ; O = ok )'


def ask(call, text, mode=Q.ALL_SOLUTIONS):
    r = call(PrologQuery, 'query', Q(mode=mode, query=text, timeout=TIMEOUT), timeout=TIMEOUT)
    assert r.ok, (r.error_kind, r.message)
    return [json.loads(s) for s in r.solutions]


def entity_property(call, scenario, name, key):
    sols = ask(call, f'''scenario_entity({scenario}, {name}, E),
                        get_dict(properties, E, Ps), get_dict({key}, Ps, V)''', mode=Q.ONCE)
    return sols[0]['V']


# The pads hold the egg through the lift iff 2 mu F >= m (g + a), a = 0.58 m/s^2 at the
# lift's peak: egg1 (0.22, 60 g) needs 0.623 N; at 3 N it has 1.32 N, at 0.08 0.48 N; at
# 2 N it has 0.88 N, a 120 g egg needs 1.25 N.
@pytest.mark.parametrize('key, kb_value, value, force, kb_outcome, outcome', [
    ('friction', 0.22, 0.08, 3, 'ok', 'slip'),          # a more slippery shell slips
    ('mass', 0.06, 0.12, 2, 'ok', 'slip'),              # a heavier egg slips
    ('breaking_force', 10.0, 20.0, 11, 'break', 'ok'),  # a stronger shell holds at 11 N
    ('breaking_force', 10.0, 5.0, 5, 'ok', 'break'),    # a weaker shell breaks at 5 N
])
def test_a_counterfactual_egg_changes_the_outcome_at_the_same_force(
        call, key, kb_value, value, force, kb_outcome, outcome):
    assert entity_property(call, 'grasping', 'egg1', key) == pytest.approx(kb_value)
    sols = ask(call, f'''
        copy_scenario(grasping, S), scenario_set_property(S, egg1, {key}, {value!r}),
        member(Sc-Which, [grasping-kb, S-variant]),
        make_projection(Sc, grasp_object, [(_, force, [{force}]), (_, position, [0.0])], TL),
        {OUTCOME}''')
    assert {s['Which']: s['O'] for s in sols} == {'kb': kb_outcome, 'variant': outcome}


@pytest.mark.parametrize('breaking_force', [3.0, 5.0])
def test_an_egg_that_breaks_as_it_is_dropped_is_broken_after_the_drop(call, breaking_force):
    # Section II's query. A weak shell breaks from the pads' rims as the heavy egg slides out
    # of the grip (their load peaks at 5.2 N, 4.9 N on a hull of 362 vertices), or else when
    # it lands (4.6-5.1 N averaged over the break window, on hulls of 178-738 vertices);
    # either way broken(egg1) holds after the drop.
    # 2.3 N lifts the 100 g egg (friction 0.22: 2 * 0.22 * 2.3 = 1.01 N >= m g = 0.98 N)
    # but loses it at the lift's peak (< m (g + a) = 1.04 N); measured drop: 2.28-2.31 N.
    sols = ask(call, f'''
        create_scenario(S),
        add_to_scenario(S, [kitchen_env, pr2_robot, egg1]),
        scenario_set_property(S, egg1, mass, 0.1),
        scenario_set_property(S, egg1, breaking_force, {breaking_force}),
        make_projection(S, grasp_object, [(_, force, [2.3])], TL),
        with_timeline(TL, ( occurs(Evt, T1), typeOf(Evt, dropping), objOf(Evt, egg1),
                            after(T2, T1), holds(F, T2), objOf(F, egg1) ))''')
    fluents = {json.dumps(s['F'], sort_keys=True) for s in sols}
    for name, args in (('broken', ['egg1']), ('on', ['egg1', 'table1'])):
        assert json.dumps({'functor': name, 'args': args}, sort_keys=True) in fluents


def test_the_grippers_limits_act_through_the_service(call):
    sols = ask(call, f'''
        copy_scenario(grasping, S), scenario_set_property(S, pr2_gripper, max_force, 4.0),
        member(Sc-Which, [grasping-kb, S-capped]),
        make_projection(Sc, grasp_object, [(_, force, [11]), (_, position, [0.0])], TL),
        {OUTCOME}''')
    assert {s['Which']: s['O'] for s in sols} == {'kb': 'break', 'capped': 'ok'}


@pytest.mark.parametrize('entity, key', [('floor1', 'rolling_friction'), ('egg1', 'colour'),
                                         ('kitchen_env', 'friction')])
def test_a_property_the_simulator_does_not_build_from_is_refused(call, entity, key):
    r = call(PrologQuery, 'query', Q(mode=Q.ONCE, query=f'''
        copy_scenario(grasping, S), scenario_set_property(S, {entity}, {key}, 0.5)''',
        timeout=TIMEOUT), timeout=TIMEOUT)
    assert not r.ok and r.error_kind == 'domain_error'
    assert key in r.message and entity in r.message and 'builds it from' in r.message


# The pours below take each projection's time limit as 600 s (make_projection/5): the
# default limit of wall-clock time is not meant for a loaded machine's 1 s holds.


def test_pouring_at_a_larger_angle_puts_more_on_the_pan_and_a_centred_pour_lands_on_it(call):
    sols = ask(call, '''
        make_projection(pouring, pour,
                        [(A, angle, [1.84, 2.14]), (T, time, [1.0]), (P, position, [0.0])],
                        600.0, TL),
        quantity(particles_on(pancake_maker1), N, TL),
        quantity(centroid_offset_x(pancake_maker1), X, TL),
        quantity(centroid_offset_y(pancake_maker1), Y, TL)''')
    assert [s['A'] for s in sols] == [1.84, 2.14]
    low, high = sols
    assert 0 < low['N'] < high['N']
    radius = entity_property(call, 'pouring', 'pancake_maker1', 'radius')
    assert radius == pytest.approx(0.15)
    for s in sols:
        assert math.hypot(s['X'], s['Y']) < radius, s


def test_a_query_selects_the_pour_with_most_mix_on_the_pan_and_no_spill(call):
    # Poured 13 cm off the pan's centre (2 cm inside its rim), the batter runs over the edge.
    grid = '[(A, angle, [1.84, 2.14]), (T, time, [1.0]), (P, position, [-0.13, 0.0])]'
    measured = ask(call, f'''
        make_projection(pouring, pour, {grid}, 600.0, TL),
        quantity(particles_on(pancake_maker1), N, TL),
        quantity(particles_spilled(pancake_mix1), S, TL),
        ( occurs(spill(pancake_mix1), _, TL) -> Spill = yes ; Spill = no )''')
    assert len(measured) == 4
    # A spill puts particles neither in the cup nor on the pan; the converse need not hold:
    # cohesive batter may cling to the outside of the cup's lip without reaching the table.
    assert all(s['S'] > 0 for s in measured if s['Spill'] == 'yes')
    assert any(s['Spill'] == 'yes' for s in measured)   # the pile near the edge runs over
    (best,) = ask(call, f'''
        aggregate_all(max(N, A-P),
                      ( make_projection(pouring, pour, {grid}, 600.0, TL),
                        \\+ occurs(spill(_), _, TL),
                        quantity(particles_on(pancake_maker1), N, TL) ),
                      max(Most, Angle-Position))''')
    dry = [s for s in measured if s['Spill'] == 'no']
    top = max(dry, key=lambda s: s['N'])
    assert best['Most'] == top['N']
    assert (best['Angle'], best['Position']) == (top['A'], top['P'])


def test_turning_in_table_iiis_form_is_ok_at_a_small_angle_and_fails_at_a_large_one(call):
    sols = ask(call, '''
        make_projection(turning, turn_pancake, [(A, angle, [0.1, 0.9])], TL),
        ( holds(upsidedown, _, TL) -> O = ok ; O = fail )''')
    assert [(s['A'], s['O']) for s in sols] == [(0.1, 'ok'), (0.9, 'fail')]


def test_a_pancake_made_from_a_pours_particles_turns_at_a_small_angle_only(call):
    # The paper's Fig. 7 end to end: pour, build the pancake from the particles that
    # stayed on the pan, turn it with the spatula.
    sols = ask(call, '''
        make_projection(pouring, pour,
                        [(_, angle, [2.14]), (_, time, [0.5]), (_, position, [0.0])], 600.0,
                        PourTL),
        quantity(particles_on(pancake_maker1), N, PourTL),
        quantity(particles_on_positions(pancake_maker1), Points, PourTL),
        create_scenario(S),
        add_to_scenario(S, [kitchen_env, pr2_robot, pancake_maker1, spatula1,
                            object(pancake, _{name: poured, particles: Points})]),
        scenario_entity(S, poured, Pancake), get_dict(properties, Pancake, Props),
        get_dict(particles, Props, Joined0), length(Joined0, Joined),
        make_projection(S, turn_pancake, [(A, angle, [0.1, 0.3, 0.9])], TL),
        ( holds(upside_down(poured), _, TL) -> O = ok ; O = fail )''')
    outcomes = dict((s['A'], s['O']) for s in sols)
    # Which of the small angles turns a poured pancake hangs on the details of its pile
    # (Table III with the poured pancake is not monotonic in angle, bench/RESULTS.md): one
    # of them must, the large one must not.
    assert 'ok' in (outcomes[0.1], outcomes[0.3]) and outcomes[0.9] == 'fail', outcomes
    # The pancake is the heap on the pan: the factory joins every particle its flood fill
    # reaches and leaves out a stray further than joint_radius from all (one of 193 here).
    assert sols[0]['N'] > 50 and 0.95 * sols[0]['N'] <= sols[0]['Joined'] <= sols[0]['N']


def _pour_goals(scenario: str, tl: str) -> str:
    """Project the pour in ``scenario``; bind Bag<tl>, N<tl>, EF<tl>; remove the timeline."""
    return f'''
        make_projection({scenario}, pour, Ps, 600.0, {tl}),
        timeline_property({tl}, meta(M{tl})),
        get_dict(bag, M{tl}, Bag{tl}), quantity(particles_on(pancake_maker1), N{tl}, {tl}),
        findall(E-T, occurs(E, T, {tl}), E{tl}), findall(F-T, holds(F, T, {tl}), F{tl}),
        EF{tl} = E{tl}-F{tl}, timeline_remove({tl})'''


def test_a_pour_in_two_scenarios_built_alike_gives_one_timeline(call):
    """Two scenarios built alike are one projection (the cache key is the scenario's
    content, not its name): S2's pour finds the bag S1's made, as S1's again does, and
    each translation of it is the same timeline."""
    sols = ask(call, f'''
        Members = [kitchen_env, pr2_robot, pancake_maker1, cup1],
        create_scenario(S1), add_to_scenario(S1, Members), scenario_description(S1, D1),
        create_scenario(S2), add_to_scenario(S2, Members), scenario_description(S2, D2),
        ( get_dict(entities, D1, Es1), get_dict(entities, D2, Es2), Es1 =@= Es2
        -> Alike = true ; Alike = false ),
        Ps = [(_, angle, [1.99]), (_, time, [0.5]), (_, position, [0.0])],
        {_pour_goals('S1', 'A')}, {_pour_goals('S2', 'B')}, {_pour_goals('S1', 'C')},
        delete_scenario(S1), delete_scenario(S2)''', mode=Q.ONCE)
    s = sols[0]
    assert s['S1'] != s['S2'] and s['Alike'] == 'true'
    assert len({s['A'], s['B'], s['C']}) == 3       # each translated anew
    assert s['BagB'] == s['BagA'] == s['BagC']      # S2, and S1 again: S1's bag
    assert s['NA'] == s['NB'] == s['NC'] and s['NA'] > 0
    assert s['EFA'] == s['EFB'] == s['EFC']
