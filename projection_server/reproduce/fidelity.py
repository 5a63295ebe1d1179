"""Convergence of the experiments: the same queries at the programs' settings and at a finer
reference (a 4x finer time step with 4x the solver iterations), cell by cell.

A prediction is a property of the physics only if refining the simulation does not change
it. The reference runs through the same service with make_projection/5's physics option:

    >>> physics = reference_physics(client, 'pour')        # {'rate_hz': 960, ...}
    >>> reference = run_experiment(client, TABLE_II_POURING, physics=physics)
    >>> converged(result, reference).summary()
    '27/27 cells agree with the 4x finer reference; counts within 12 % (largest)'
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Mapping

    from projection_server.client import PrologClient
    from projection_server.reproduce.experiments import Result

__all__ = ['COUNT_COLUMNS', 'FACTOR', 'REFERENCE_TOLERANCES', 'Convergence', 'converged',
           'reference_physics']

FACTOR = 4   # the reference's time step is this much finer, with this many more iterations

# How close a measure must come to the reference's: particle counts within 15 % (at least
# 3 particles, 1 % of the batch: a pile's count moves by a few particles between any two
# runs that differ in round-off), centroid offsets within 1 cm, roundness within 0.1; half
# the tolerances the comparison with the paper uses, or less. Outcomes must be equal.
COUNT_COLUMNS = ('pan', 'spill')
REFERENCE_TOLERANCES = {
    'pan': lambda ref: max(3.0, 0.15 * abs(ref)),
    'spill': lambda ref: max(3.0, 0.15 * abs(ref)),
    'off_x': lambda ref: 0.01,
    'off_y': lambda ref: 0.01,
    'round': lambda ref: 0.1,
}


def reference_physics(client: PrologClient, program: str,
                      factor: int = FACTOR) -> dict[str, int]:
    """``rate_hz`` and ``solver_iterations`` ``factor`` times the program's defaults (as
    the server reports them), within their ranges."""
    settings = {}
    for name in ('rate_hz', 'solver_iterations'):
        solution = client.once(f'projection_physics_setting({program}, {name}, D), '
                               'get_dict(default, D, Default), get_dict(max, D, Max)')
        if solution is None:
            raise LookupError(f'the server has no physics setting {name} for {program}')
        settings[name] = min(int(solution['Default']) * factor, int(solution['Max']))
    return settings


@dataclass
class Convergence:
    """Cell-by-cell agreement of a result with the same query's run at finer settings."""

    result: Result
    reference: Result
    agree: int
    total: int
    differences: list[tuple[tuple, str, Any, Any]]   # (key, column, reference, ours)
    count_deviation: float | None   # largest |ours - ref| / ref of the counts (ref > 0)

    def summary(self, limit: int = 4) -> str:
        finer = _describe(self.reference.physics)
        text = f'{self.agree}/{self.total} cells agree with the reference ({finer})'
        if self.count_deviation is not None:
            text += f'; counts within {100 * self.count_deviation:.0f} % (largest)'
        shown = [f'{self.result.experiment.describe(key)} {column}: reference '
                 f'{_show(theirs)}, ours {_show(ours)}'
                 for key, column, theirs, ours in self.differences[:limit]]
        more = len(self.differences) - len(shown)
        if shown:
            text += '; differs at ' + '; '.join(shown) + (f'; and {more} more' if more else '')
        return text


def converged(result: Result, reference: Result) -> Convergence:
    """Compare ``result`` with ``reference`` (the same experiment at finer settings): outcomes
    must be equal, numbers within :data:`REFERENCE_TOLERANCES`. Cells only one of them has
    count as differing."""
    exp = result.experiment
    ours, theirs = result.by_key(), reference.by_key()
    agree, total, diffs, deviation = 0, 0, [], None
    for key in [k for k in exp.grid(result.quick) if k in ours or k in theirs]:
        mine, ref = ours.get(key), theirs.get(key)
        if exp.qualitative:
            cells = [(exp.measures[0].column, _value(ref), _value(mine))]
        else:
            cells = [(m.column, (_value(ref) or {}).get(m.column),
                      (_value(mine) or {}).get(m.column)) for m in exp.measures]
        for column, ref_value, my_value in cells:
            total += 1
            tolerance = REFERENCE_TOLERANCES.get(column)
            if mine is not None and ref is not None and _agrees(tolerance, ref_value, my_value):
                agree += 1
            else:
                diffs.append((key, column, ref_value, my_value))
            if (column in COUNT_COLUMNS and isinstance(ref_value, (int, float))
                    and isinstance(my_value, (int, float)) and ref_value > 0):
                off = abs(my_value - ref_value) / ref_value
                deviation = off if deviation is None else max(deviation, off)
    return Convergence(result, reference, agree, total, diffs, deviation)


def _agrees(tolerance: Any, reference: Any, ours: Any) -> bool:
    if reference is None or ours is None:
        return reference is None and ours is None
    if tolerance is None or isinstance(reference, str) or isinstance(ours, str):
        return reference == ours
    return abs(float(ours) - float(reference)) <= tolerance(float(reference)) + 1e-12


def _show(value: Any) -> str:
    if value is None:
        return '—'
    return f'{value:.3g}' if isinstance(value, float) else str(value)


def _value(run: Any) -> Any:
    return None if run is None else run.value


def _describe(physics: Mapping[str, float] | None) -> str:
    if not physics:
        return "the programs' settings"
    return ', '.join(f'{k} {_show(v)}' for k, v in physics.items())
