"""make_projection's options as Prolog reads them, in this process's SWI-Prolog (janus): the
default time limit of a projection grows with the physics a query asks for."""

from __future__ import annotations

import pytest


@pytest.fixture(scope='module')
def prolog():
    from projection_server.service import prolog_bridge

    prolog_bridge.load()
    import janus_swi

    return janus_swi


def timeout(prolog, program: str, options: str) -> float:
    return prolog.query_once(
        f'term_string(_O, "{options}"), projection:projection_options({program}, _O, T, _, _)'
    )['T']


DEFAULT = 300   # s, projection_default_timeout/1


def test_the_default_limit_is_300_s(prolog):
    assert timeout(prolog, 'grasp_object', '[]') == DEFAULT


def test_finer_physics_multiply_the_default_limit_by_their_cost(prolog):
    assert timeout(prolog, 'grasp_object',
                   '[physics(_{rate_hz: 960, solver_iterations: 400})]') == DEFAULT * 4 * 4
    # the program's own settings are the base: the turn runs with fewer iterations
    own = prolog.query_once('projection_physics_setting(turn_pancake, solver_iterations, S), '
                            'get_dict(default, S, D)')['D']
    rate = prolog.query_once('projection_physics_setting(turn_pancake, rate_hz, S), '
                             'get_dict(default, S, D)')['D']
    assert own < 100
    assert timeout(prolog, 'turn_pancake',
                   f'[physics(_{{rate_hz: {4 * rate}, solver_iterations: {4 * own}}})]') == DEFAULT * 16
    assert timeout(prolog, 'plan', '[physics(_{rate_hz: 480})]') == DEFAULT * 2
    # and the engine's: MuJoCo steps at 120 Hz (config/physics.yaml)
    assert timeout(prolog, 'grasp_object', '[physics(_{engine: mujoco, rate_hz: 480})]'
                   ) == DEFAULT * 4
    assert timeout(prolog, 'grasp_object', '[physics(_{engine: mujoco})]') == DEFAULT


def test_coarser_physics_keep_the_default_and_a_given_limit_is_kept(prolog):
    assert timeout(prolog, 'grasp_object', '[physics(_{rate_hz: 120})]') == DEFAULT
    assert timeout(prolog, 'grasp_object', '[timeout(5), physics(_{rate_hz: 960})]') == 5


def test_only_keeps_the_combinations_it_names_in_the_grids_order(prolog):
    found = prolog.query_once(
        'projection:only_combinations([only([[9, b], [1, a]])], '
        '[choice(_, f, [1, 5, 9]), choice(_, p, [a, b])], [_{f: 1, p: a}, _{f: 1, p: b}, '
        '_{f: 9, p: b}], All)')['All']
    assert [(d['f'], d['p']) for d in found] == [(1, 'a'), (9, 'b')]


def test_only_must_be_a_list_of_lists(prolog):
    with pytest.raises(prolog.PrologError, match='Type error'):
        prolog.query_once('projection:check_option(only([5]))')
