"""Maximal intervals from sampled booleans, and merging of short gaps. Pure functions.

A fluent sampled at times ``t_0 < t_1 < ...`` holds on the closed interval from the first to
the last sample of each run of true samples. Runs separated by a gap shorter than a
threshold (from the end of one to the start of the next) are merged into one interval, so
that contact chatter of a sample or two does not split a fluent.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

__all__ = [
    'Interval',
    'fluent_intervals',
    'holds_at',
    'intervals_from_samples',
    'merge_gaps',
]

Interval = tuple[float, float]


def intervals_from_samples(times: Sequence[float], values: Sequence[bool]) -> list[Interval]:
    """Maximal runs of true ``values`` as ``(first time, last time)`` of each run."""
    if len(times) != len(values):
        raise ValueError(f'{len(times)} times but {len(values)} values')
    intervals: list[Interval] = []
    start = None
    for i, (time, value) in enumerate(zip(times, values)):
        if value and start is None:
            start = time
        elif not value and start is not None:
            intervals.append((start, times[i - 1]))
            start = None
    if start is not None:
        intervals.append((start, times[-1]))
    return intervals


def merge_gaps(intervals: Iterable[Interval], max_gap: float) -> list[Interval]:
    """Merge consecutive intervals whose gap (next start - previous end) is below ``max_gap``.

    ``intervals`` must be sorted and disjoint, as :func:`intervals_from_samples` makes them.
    """
    merged: list[Interval] = []
    for start, end in intervals:
        if merged and start - merged[-1][1] < max_gap:
            merged[-1] = (merged[-1][0], max(merged[-1][1], end))
        else:
            merged.append((start, end))
    return merged


def fluent_intervals(times: Sequence[float], values: Sequence[bool],
                     max_gap: float) -> list[Interval]:
    """:func:`intervals_from_samples`, then :func:`merge_gaps`."""
    return merge_gaps(intervals_from_samples(times, values), max_gap)


def holds_at(intervals: Iterable[Interval], time: float) -> bool:
    """Whether ``time`` lies in one of the closed ``intervals``."""
    return any(start <= time <= end for start, end in intervals)
