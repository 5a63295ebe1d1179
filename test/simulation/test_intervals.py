"""The interval logic of timelines: maximal intervals and gap merging."""

from __future__ import annotations

import pytest

from projection_server.timeline.intervals import (
    fluent_intervals,
    holds_at,
    intervals_from_samples,
    merge_gaps,
)

TIMES = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]


def test_maximal_runs_of_true_samples_become_intervals():
    values = [False, True, True, False, False, True, False]
    assert intervals_from_samples(TIMES, values) == [(0.1, 0.2), (0.5, 0.5)]


def test_a_run_at_the_end_closes_at_the_last_sample():
    assert intervals_from_samples(TIMES, [False] * 5 + [True] * 2) == [(0.5, 0.6)]


def test_all_true_is_one_interval_and_all_false_none():
    assert intervals_from_samples(TIMES, [True] * 7) == [(0.0, 0.6)]
    assert intervals_from_samples(TIMES, [False] * 7) == []


def test_no_samples_no_intervals():
    assert intervals_from_samples([], []) == []


def test_times_and_values_must_match():
    with pytest.raises(ValueError):
        intervals_from_samples(TIMES, [True])


def test_gaps_below_the_threshold_are_merged():
    assert merge_gaps([(0.0, 1.0), (1.05, 2.0), (3.0, 4.0)], 0.1) == [(0.0, 2.0), (3.0, 4.0)]


def test_gaps_at_the_threshold_are_kept():
    assert merge_gaps([(0.0, 1.0), (1.5, 2.0)], 0.5) == [(0.0, 1.0), (1.5, 2.0)]


def test_merging_chains_across_several_gaps():
    assert merge_gaps([(0.0, 0.1), (0.15, 0.2), (0.25, 0.3)], 0.1) == [(0.0, 0.3)]


def test_one_false_sample_is_chatter_for_fluents():
    values = [True, True, False, True, True, False, False]
    assert fluent_intervals(TIMES, values, 0.25) == [(0.0, 0.4)]
    assert fluent_intervals(TIMES, values, 0.0) == [(0.0, 0.1), (0.3, 0.4)]


def test_holds_at_includes_both_ends():
    assert holds_at([(1.0, 2.0)], 1.0)
    assert holds_at([(1.0, 2.0)], 2.0)
    assert not holds_at([(1.0, 2.0)], 2.5)
