"""Conditions that cannot silently lie, through the real service: a fluent, event, quantity
or object that no timeline of the scenario can have is an existence_error (before anything
is projected where a predicate takes the condition), a budget below one trial a
domain_error; a known name that did not happen still fails."""

from __future__ import annotations

import os

from projection_interfaces.srv import PrologQuery
import pytest

from test.nodes import caller, own_server

Q = PrologQuery.Request
SIM_TIMEOUT = 300.0
NAME = 'conditions_server'
BELIEF = '''copy_scenario(grasping, S),
    scenario_set_property(S, egg1, friction, uniform(0.2, 0.4))'''


@pytest.fixture(scope='module')
def bag_dir(tmp_path_factory):
    return tmp_path_factory.mktemp('conditions_bags')


@pytest.fixture(scope='module')
def conditions_server(rclpy_context, tmp_path_factory, bag_dir):
    """A node of this module's own, so that its bag directory shows what was projected."""
    with own_server(NAME, {'default_timeout': 5.0, 'max_engines': 4, 'bag_dir': str(bag_dir)},
                    tmp_path_factory) as name:
        yield name


@pytest.fixture(scope='module')
def call(conditions_server, node):
    with caller(conditions_server, node) as c:
        yield c


def ask(call, text, mode=Q.ALL_SOLUTIONS):
    from projection_server.client.bindings import decode_solution

    r = call(PrologQuery, 'query', Q(mode=mode, query=text, timeout=SIM_TIMEOUT,
                                     max_solutions=20), timeout=SIM_TIMEOUT * 2)
    return r, [decode_solution(s) for s in r.solutions]


def bags(bag_dir):
    """The projections' bags (not a worker's warm-up, which runs in a hidden directory)."""
    return sorted(name for name in os.listdir(bag_dir) if not name.startswith('.'))


def refused(call, bag_dir, text, kind='existence_error'):
    """The query's error message; it projected nothing, and the node serves on."""
    before = bags(bag_dir)
    r, _ = ask(call, text, Q.ONCE)
    assert not r.ok and r.error_kind == kind, (r.error_kind, r.message)
    assert bags(bag_dir) == before, 'projected before refusing'
    assert ask(call, 'X = still_serving')[0].ok
    return r.message


def test_a_misspelled_event_under_negation_is_refused_before_projecting(call, bag_dir):
    # 1 N slips and 11 N breaks the egg: `\+ occurs(brake, ...)` called both safe.
    message = refused(call, bag_dir, f'''{BELIEF},
        outcome_probability(S, grasp_object, [(F, force, [1, 11])], [samples(10), seed(1)],
                            TL, \\+ occurs(brake, _, TL), P)''')
    assert 'outcome_probability/7' in message and 'event brake' in message, message
    assert 'break/1' in message and 'slip/1' in message, message


def test_a_misspelled_fluent_cannot_certify_a_cell(call, bag_dir):
    message = refused(call, bag_dir, f'''{BELIEF},
        robust_parametrization(S, grasp_object, [(F, force, [3, 5])], [seed(1)], TL,
                               \\+ holds(in_griper(egg1), _, TL), Best)''')
    assert 'robust_parametrization/7' in message and 'in_griper(egg1)' in message, message
    assert 'in_gripper/1' in message, message


def test_an_unknown_quantity_to_prefer_is_refused_before_choosing(call, bag_dir):
    message = refused(call, bag_dir, f'''{BELIEF},
        robust_parametrization(S, grasp_object, [(F, force, [3, 5])],
                               [seed(1), prefer(-max_lod(egg1))], TL,
                               \\+ occurs(break, _, TL), Best)''')
    assert 'robust_parametrization/7' in message and 'max_lod(egg1)' in message, message


def test_an_unknown_quantity_in_a_condition_is_refused(call, bag_dir):
    message = refused(call, bag_dir, '''outcome_boundary(grasping, grasp_object,
        [(F, force, range(1, 11))], [], TL,
        ( quantity(max_lod(egg1), L, TL), L < 9 ), B)''')
    assert 'outcome_boundary/7' in message and 'max_lod(egg1)' in message, message
    assert 'max_load/1' in message, message


def test_an_object_not_in_the_scenario_is_refused(call, bag_dir):
    message = refused(call, bag_dir, '''best_parametrization(grasping, grasp_object,
        [(F, force, range(1, 11))], [max_projections(4)], TL,
        \\+ occurs(break(egg2), _, TL), max_load(egg1), Best)''')
    assert 'egg2 is no object of scenario grasping' in message, message
    assert 'egg1' in message and 'pr2_robot' in message and 'table1' in message, message


def test_an_unknown_objective_is_refused(call, bag_dir):
    # Without a value no trial is a candidate: the search would answer no solution.
    message = refused(call, bag_dir, '''best_parametrization(grasping, grasp_object,
        [(F, force, range(1, 11))], [max_projections(4)], TL,
        \\+ occurs(break, _, TL), particles_on(table1), Best)''')
    assert 'particles_on(table1)' in message and 'max_load/1' in message, message


def test_a_budget_below_one_trial_names_the_least(call, bag_dir):
    message = refused(call, bag_dir, f'''{BELIEF},
        best_parametrization(S, grasp_object, [(F, force, range(1, 11))],
                             [samples(73), chance(0.95), max_projections(20)], TL,
                             \\+ occurs(break, _, TL), max_load(egg1), Best)''',
                      kind='domain_error')
    assert 'max_projections(73)' in message, message


def test_a_name_no_timeline_has_is_an_error_on_a_projections_timeline(call):
    r, _ = ask(call, '''make_projection(grasping, grasp_object, [(F, force, [5])], TL),
        \\+ occurs(brake, _, TL)''')
    assert not r.ok and r.error_kind == 'existence_error', (r.error_kind, r.message)
    assert 'occurs/3' in r.message and 'scenario grasping' in r.message, r.message


def test_a_known_event_that_did_not_happen_still_fails(call, bag_dir):
    r, sols = ask(call, '''make_projection(grasping, grasp_object, [(F, force, [5])], TL),
        \\+ occurs(break, _, TL), \\+ occurs(slip(egg1), _, TL),
        findall(E, occurs(E, _, TL), Es0), term_to_atom(Es0, Es)''')
    assert r.ok, (r.error_kind, r.message)
    assert str(sols[0]['Es']) == '[grasp(egg1),lift(egg1)]', sols
    assert bags(bag_dir), 'a projection leaves its bag where refused() looks for one'


def test_a_pours_vocabulary_has_its_particles_and_a_grasps_has_not(call):
    r, sols = ask(call, '''projection_vocabulary(pouring, P),
        projection_vocabulary(grasping, G),
        get_dict(quantities, P, PQs), get_dict(quantities, G, GQs), get_dict(objects, G, Os),
        ( memberchk(particles_on/1, PQs) -> InPour = yes ; InPour = no ),
        ( memberchk(particles_on/1, GQs) -> InGrasp = yes ; InGrasp = no ),
        ( memberchk(egg1, Os) -> Egg = yes ; Egg = no )''')
    assert r.ok, (r.error_kind, r.message)
    assert (sols[0]['InPour'], sols[0]['InGrasp'], sols[0]['Egg']) == ('yes', 'no', 'yes')


def test_a_stepped_range_without_values_is_an_error_not_no_answer(call, bag_dir):
    message = refused(call, bag_dir, '''make_projection(grasping, grasp_object,
        [(F, force, range(11, 1, 1))], TL)''', kind='domain_error')
    assert 'range(11,1,1)' in message.replace(' ', ''), message
