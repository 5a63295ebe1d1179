"""The Optuna studies behind best_parametrization/8 (projection_server/search.py), without
simulations: asked values, seeds, infeasible and failed trials, the bounded store."""

from __future__ import annotations

import pytest

from projection_server import search


def run(seed, budget=16, feasible=lambda x: True, batch=2):
    """Trials of a study maximising x over [0, 1]; their values, in order."""
    study = search.create([['x', 0.0, 1.0]], seed, budget)
    values = []
    try:
        for _ in range(budget // batch):
            for trial in search.ask(study, batch):
                x = trial['params']['x']
                search.tell(study, trial['trial'], x, feasible(x))
                values.append(x)
    finally:
        search.release(study)
    return values


def test_asked_values_lie_in_the_range_and_are_numbered_in_order():
    study = search.create([['force', 0.5, 20.0], ['position', -0.02, 0.02]], 0, 8)
    trials = search.ask(study, 3)
    search.release(study)
    assert [t['trial'] for t in trials] == [0, 1, 2]
    for t in trials:
        assert 0.5 <= t['params']['force'] <= 20.0
        assert -0.02 <= t['params']['position'] <= 0.02


def test_the_same_seed_asks_the_same_trials_and_another_seed_others():
    assert run(3) == run(3)
    assert run(3) != run(4)


def test_infeasible_trials_steer_the_sampler_below_the_constraint():
    # The objective grows with x; the constraint fails above 0.6. After the random start
    # (half the budget), TPE samples more feasible values than without the constraint.
    start = search.startup_trials(16)
    constrained = run(0, feasible=lambda x: x <= 0.6)[start:]
    free = run(0)[start:]
    assert sum(x <= 0.6 for x in constrained) > sum(x <= 0.6 for x in free)


def test_trials_are_told_feasible_infeasible_or_failed():
    study = search.create([['x', 0.0, 1.0]], 0, 4)
    asked = search.ask(study, 4)
    search.tell(study, asked[0]['trial'], 0.5, True)
    search.tell(study, asked[1]['trial'], 0.9, False)
    search.tell(study, asked[2]['trial'], None, True)
    told = search.trials(study)
    search.release(study)
    assert [(t['state'], t['value'], t['feasible']) for t in told] == [
        ('COMPLETE', 0.5, True), ('COMPLETE', 0.9, False), ('FAIL', None, None),
        ('RUNNING', None, None)]


def test_a_trial_is_told_once():
    study = search.create([['x', 0.0, 1.0]], 0, 4)
    (trial,) = search.ask(study, 1)
    search.tell(study, trial['trial'], 0.5, True)
    with pytest.raises(search.SearchError, match='no running trial'):
        search.tell(study, trial['trial'], 0.5, True)
    search.release(study)


def test_a_released_study_is_gone_and_releasing_it_again_is_harmless():
    study = search.create([['x', 0.0, 1.0]], 0, 4)
    search.release(study)
    search.release(study)
    with pytest.raises(search.SearchError, match='released or forgotten'):
        search.ask(study, 1)


def test_at_most_max_studies_are_kept_the_oldest_forgotten():
    before = search.studies()
    ids = [search.create([['x', 0.0, 1.0]], 0, 4) for _ in range(search.MAX_STUDIES + 1)]
    assert search.studies() == search.MAX_STUDIES
    with pytest.raises(search.SearchError):
        search.ask(ids[0], 1)
    for study in ids:
        search.release(study)
    assert search.studies() == 0 <= before


def test_a_small_budget_is_not_all_random_start():
    assert search.startup_trials(4) == 2
    assert search.startup_trials(16) == 8
    assert search.startup_trials(100) == 10
