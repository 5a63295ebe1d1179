"""The statistics of robust_parametrization/7: certifying counts and bounds, the paired
elimination, the stopping rule and the rules among equals."""

from __future__ import annotations

import math

import pytest

from projection_server import selection


def test_59_fresh_successes_prove_a_risk_of_5_percent_and_93_with_one_failure():
    assert selection.certify_count(0.05, 0.95) == 59
    assert selection.clopper_pearson(59, 59, 0.95)[0] >= 0.95
    assert selection.clopper_pearson(58, 58, 0.95)[0] < 0.95
    assert selection.clopper_pearson(92, 93, 0.95)[0] >= 0.95 - 1e-6
    assert selection.clopper_pearson(91, 92, 0.95)[0] < 0.95


@pytest.mark.parametrize('k, n', [(0, 10), (3, 10), (10, 10), (17, 40)])
def test_clopper_pearson_bounds_hold_their_tail_probabilities(k, n):
    low, high = selection.clopper_pearson(k, n, 0.95)
    tail = lambda lo, hi, p: sum(math.comb(n, i) * p ** i * (1 - p) ** (n - i)
                                 for i in range(lo, hi + 1))
    if k > 0:
        assert tail(k, n, low) == pytest.approx(0.05, abs=1e-6)
    if k < n:
        assert tail(0, k, high) == pytest.approx(0.05, abs=1e-6)


def test_the_sign_test_counts_only_the_worlds_where_two_cells_differ():
    assert selection.sign_test(5, 0) == pytest.approx(1 / 32)
    assert selection.sign_test(0, 0) == 1.0
    assert selection.sign_test(3, 3) > 0.5


def test_a_cell_that_fails_everywhere_goes_after_the_first_round_by_the_risk_rule():
    first = selection.first_round(2, 0.95, 0.05, 4)
    outcomes = [[0] * first, [1] * first]
    assert selection.step(outcomes, 0.95, 0.05, 0.05, 30) == {'eliminate': [0], 'park': [], 'stop': True}


def test_paired_worlds_separate_cells_that_independent_counts_would_not():
    # b beats c in 8 worlds where they differ; they agree (both fail) in 12 others
    b = [1] * 8 + [0] * 12
    c = [0] * 20
    step = selection.step([b, c, [1] * 6 + [0] * 14], 0.95, 0.99, 0.05, 40)
    assert 1 in step['eliminate'] and 0 not in step['eliminate']


def test_elimination_does_not_depend_on_the_cells_order():
    cells = [[1, 1, 1, 1, 1, 1], [0, 0, 0, 0, 0, 0], [1, 0, 1, 1, 1, 1], [1, 1, 1, 1, 1, 1]]
    forward = selection.step(cells, 0.95, 0.05, 0.05, 30)['eliminate']
    backward = selection.step(cells[::-1], 0.95, 0.05, 0.05, 30)['eliminate']
    assert sorted(3 - c for c in backward) == forward == [1]


def test_choosing_goes_on_while_the_leaders_disagree_and_stops_when_settled():
    n = 10
    agree = [[1] * n, [1] * n, [1] * (n - 2) + [0, 0]]
    assert selection.step(agree, 0.95, 0.05, 0.05, 30)['stop']
    disagree = [[1] * (n - 1) + [0], [0] + [1] * (n - 1)]   # as good, not alike
    assert not selection.step(disagree, 0.95, 0.05, 0.05, 30)['stop']
    assert selection.step(disagree, 0.95, 0.05, 0.05, n)['stop']   # the cap


def test_an_edge_rule_waits_as_many_agreeing_worlds_as_its_certificate_has():
    # 2..5 N agreed in 10 worlds: settled for the margin rule; the gentlest of them may still
    # slip in the 11th, and a prefer or near rule would take it.
    agree = [None] + [[1] * 10 for _ in range(4)]
    assert selection.step(agree, 0.95, 0.1, 0.05, 30)['stop']
    assert not selection.step(agree, 0.95, 0.1, 0.05, 30, 29)['stop']
    agree29 = [None] + [[1] * 29 for _ in range(4)]
    assert selection.step(agree29, 0.95, 0.1, 0.05, 30, 29)['stop']


def test_an_edge_rule_parks_the_leaders_it_ranks_after_its_first_two():
    forces = [[1.0], [2.0], [3.0], [4.0], [5.0]]
    agree = [None] + [[1] * 10 for _ in range(4)]
    # the gentlest first: the mean load grows with the force
    ranked = selection.choose(agree, forces, 0.05, 'prefer', quantities=[None, 2, 3, 4, 5],
                              sign=-1)['ranked']
    assert ranked == [1, 2, 3, 4]
    step = selection.step(agree, 0.95, 0.1, 0.05, 30, 29, ranked)
    assert step['park'] == [3, 4] and not step['stop']
    assert selection.step(agree, 0.95, 0.1, 0.05, 30)['park'] == []   # margin: none
    # 2 N slipped in a later world: 3 N leads, and a parked 4 N is taken over 2 N
    later = [None, [1] * 20 + [0] * 2, [1] * 22, [1] * 10, [1] * 10]
    chosen = selection.choose(later, forces, 0.05, 'prefer', quantities=[None, 2, 3, 4, 5],
                              sign=-1)
    assert chosen['cell'] == 2 and chosen['ranked'] == [2, 3, 4]


def test_the_rules_among_equals():
    # forces 1..5 N: 1 N eliminated, 5 N failed once, 2, 3, 4 N equals
    outcomes = [None, [1] * 8, [1] * 8, [1] * 8, [1] * 7 + [0]]
    values = [[1], [2], [3], [4], [5]]
    margin = selection.choose(outcomes, values, 0.05, 'margin')
    assert margin['equals'] == [1, 2, 3] and margin['cell'] == 2   # farthest from 1 and 5 N
    near = selection.choose(outcomes, values, 0.05, 'near', near=[4])
    assert near['cell'] == 3   # keeps the default when it is an equal
    gentlest = selection.choose(outcomes, values, 0.05, 'prefer', sign=-1,
                                quantities=[None, 2.0, 3.0, 4.0, 5.0])
    assert gentlest['cell'] == 1
    # an indifference zone of 0.2 takes 5 N (7 of 8) among the equals
    assert 4 in selection.choose(outcomes, values, 0.2, 'margin')['equals']


def test_ties_go_to_the_centre_not_to_the_grids_order():
    outcomes = [[1] * 5, [1] * 5, [1] * 5]
    values = [[3], [1], [2]]
    assert selection.choose(outcomes, values, 0.05, 'margin')['cell'] == 2


def test_a_certificate_comes_from_its_fresh_worlds_only():
    assert selection.certificate(59, 59, 0.95, 0.05)['certified'] is True
    short = selection.certificate(10, 10, 0.95, 0.05)
    assert short['certified'] is False and short['p'] == 1.0 and short['low'] < 0.8
