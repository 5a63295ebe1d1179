"""Why ours and the paper's tables differ, read off the results (not asserted a priori).

    >>> explain(result)
    'the paper's slip at (-0.02, f5) is an isolated outlier between two ok cells; ...'

Qualitative tables are read as ordered outcomes along the column parameter (``slip`` <
``ok`` < ``break``/``fail``): where each row changes outcome, in the paper and in ours, and
which of the paper's cells break that order. Quantitative tables are summarised per
measure: whether ours lie systematically above or below the paper's, and how each measure
trends along each parameter in both.
"""

from __future__ import annotations

from statistics import mean
from typing import Any, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Sequence

    from projection_server.reproduce.experiments import Experiment, Result

__all__ = ['OUTCOME_RANK', 'explain']

# Outcomes ordered by the load on the object: too little grip, right, too much.
OUTCOME_RANK = {'slip': 0, 'ok': 1, 'break': 2, 'fail': 2}

# What our model says decides each qualitative outcome (simulation/, config/physics.yaml).
MECHANISM = {
    'grasp_object': 'slip and break follow friction and contact load',
}


def explain(result: Result) -> str:
    """One line on why ours and the paper's cells differ, derived from ``result``'s runs."""
    exp = result.experiment
    if result.skipped or not result.runs:
        return 'nothing to explain: no projections ran'
    if exp.qualitative:
        return _qualitative(result)
    return _quantitative(result)


# -- qualitative: outcomes along the column parameter -------------------------------------

def _rows(result: Result) -> list[tuple[Any, list[tuple[float, Any, Any]]]]:
    """[(row value, [(col value, paper, ours), ...] sorted by col value)] of the runs."""
    exp = result.experiment
    names = [p.name for p in exp.params]
    rows: dict[Any, list] = {}
    for run in result.runs:
        values = dict(zip(names, run.key))
        row = values[exp.rows] if exp.rows else None
        rows.setdefault(row, []).append((values[exp.cols], exp.paper.get(run.key), run.value))
    return [(row, sorted(cells, key=lambda c: c[0])) for row, cells in sorted(
        rows.items(), key=lambda item: (item[0] is None, item[0] or 0))]


def _monotonic(outcomes: Sequence[Any]) -> bool:
    ranks = [OUTCOME_RANK.get(o) for o in outcomes if o is not None]
    return None not in ranks and all(a <= b for a, b in zip(ranks, ranks[1:]))


def _changes(cells: Sequence[tuple[float, Any]], show) -> str:
    """Where the outcome changes along the row: 'ok→fail between 0.4 and 0.5'."""
    parts = []
    for (c0, o0), (c1, o1) in zip(cells, cells[1:]):
        if o0 is not None and o1 is not None and o0 != o1:
            parts.append(f'{o0}→{o1} between {show(c0)} and {show(c1)}')
    return ', '.join(parts) or 'no change'


def _qualitative(result: Result) -> str:
    exp = result.experiment
    by_name = {p.name: p for p in exp.params}
    col = by_name[exp.cols]
    row_param = by_name.get(exp.rows) if exp.rows else None
    rows = _rows(result)
    outliers, changes = [], []
    for row, cells in rows:
        where_row = f'{row_param.show(row)}, ' if row_param else ''
        papers = [p for _, p, _ in cells]
        for i in range(1, len(cells) - 1):
            before, here, after = papers[i - 1], papers[i], papers[i + 1]
            # a differing cell of the paper's that breaks its row's order
            rest = papers[:i] + papers[i + 1:]
            if (here is not None and before is not None and before == after != here
                    and cells[i][2] != here and _monotonic(rest)):
                outliers.append(f"the paper's {here} at ({where_row}{col.show(cells[i][0])}) "
                                f'is an isolated outlier between two {before} cells')
        theirs = _changes([(c, p) for c, p, _ in cells], col.show)
        ours = _changes([(c, o) for c, _, o in cells], col.show)
        if theirs != ours:
            label = f'{exp.rows} {row_param.show(row)}: ' if row_param else ''
            changes.append(f'{label}paper {theirs}; ours {ours}')
    parts = list(outliers)
    ours_monotonic = all(_monotonic([o for _, _, o in cells]) for _, cells in rows)
    paper_monotonic = all(_monotonic([p for _, p, _ in cells]) for _, cells in rows)
    mechanism = MECHANISM.get(exp.program)
    order = ' → '.join(sorted({o for _, cells in rows for _, _, o in cells if o},
                              key=lambda o: OUTCOME_RANK.get(o, 99)))
    if ours_monotonic:
        text = (f'our outcomes are monotonic in {col.name} ({order})'
                + ('' if len(rows) == 1 else ' in every row'))
        text += f' because {mechanism}' if mechanism else ''
        if not paper_monotonic:
            text += ", the paper's are not"
        parts.append(text)
    else:
        parts.append(f'our outcomes are not monotonic in {col.name}')
    if changes:
        parts.append('change points: ' + '; '.join(changes))
    else:
        parts.append('the change points agree: ' + '; '.join(
            (f'{exp.rows} {row_param.show(row)}: ' if row_param else '')
            + _changes([(c, o) for c, _, o in cells], col.show) for row, cells in rows))
    return '; '.join(parts)


# -- quantitative: per measure, level and trends --------------------------------------------

def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, (int, float)) else None


def _fmt(value: float) -> str:
    return f'{value:.0f}' if abs(value) >= 10 else f'{value:.3g}'


def _quantitative(result: Result) -> str:
    exp = result.experiment
    parts = []
    for m in exp.measures:
        pairs = []          # (key, paper, ours) where both are numbers
        undefined = 0       # the paper has no value, ours has one
        for run in result.runs:
            theirs = exp.paper.get(run.key, {}).get(m.column)
            ours = run.value.get(m.column)
            if theirs is None and _number(ours) is not None and run.key in exp.paper:
                undefined += 1
            if _number(theirs) is not None and _number(ours) is not None:
                pairs.append((run.key, float(theirs), float(ours)))
        line = _measure_line(exp, m, pairs, undefined, _totals(result))
        if line:
            parts.append(line)
    return '; '.join(parts) or 'no measure differs beyond its tolerance'


def _totals(result: Result) -> list[float]:
    """Our particles poured per run (pan + spill), where both are numbers."""
    totals = []
    for run in result.runs:
        pan, spill = _number(run.value.get('pan')), _number(run.value.get('spill'))
        if pan is not None and spill is not None:
            totals.append(pan + spill)
    return totals


def _measure_line(exp: Experiment, m: Any, pairs: list, undefined: int,
                  totals: list[float]) -> str | None:
    tol = m.tolerance or (lambda v: 0.0)
    higher = [k for k, t, o in pairs if o > t + tol(t) + 1e-12]
    lower = [k for k, t, o in pairs if o < t - tol(t) - 1e-12]
    bits = []
    n = len(pairs)
    if n and (higher or lower):
        if len(higher) >= 0.75 * n:
            bits.append(f'ours higher in {len(higher)}/{n}')
        elif len(lower) >= 0.75 * n:
            bits.append(f'ours lower in {len(lower)}/{n}')
        else:
            bits.append(f'{len(higher)} higher, {len(lower)} lower of {n}')
        paper_max = max(t for _, t, _ in pairs)
        ours_max = max(o for _, _, o in pairs)
        if m.column == 'pan' and totals and ours_max < 0.75 * paper_max:
            bits.append(f'ours at most {_fmt(ours_max)} (paper {_fmt(paper_max)}), '
                        f'at most {_fmt(max(totals))} poured')
        bits += _trends(exp, pairs)
    if undefined:
        bits.append(f'{undefined} the paper leaves undefined')
    if not bits:
        return None
    return f'{m.column}: ' + ', '.join(bits)


def _trends(exp: Experiment, pairs: list) -> list[str]:
    """Along each parameter with several values: whether ours and the paper's means trend
    the same way (named together) or opposite ways (with both ends)."""
    same, opposite = [], []
    for i, p in enumerate(exp.params):
        values = sorted({k[i] for k, _, _ in pairs})
        if len(values) < 2:
            continue
        groups = {v: [(t, o) for k, t, o in pairs if k[i] == v] for v in values}
        paper = {v: mean(t for t, _ in g) for v, g in groups.items()}
        ours = {v: mean(o for _, o in g) for v, g in groups.items()}
        lo, hi = values[0], values[-1]
        d_paper, d_ours = paper[hi] - paper[lo], ours[hi] - ours[lo]
        scale = max(abs(x) for x in (*paper.values(), *ours.values())) or 1.0
        if abs(d_paper) < 0.1 * scale and abs(d_ours) < 0.1 * scale:
            continue
        if (d_paper > 0) == (d_ours > 0):
            same.append((d_paper > 0, p.name))
        else:
            opposite.append(f'opposite with {p.name} (paper {_fmt(paper[lo])}→'
                            f'{_fmt(paper[hi])}, ours {_fmt(ours[lo])}→{_fmt(ours[hi])})')
    if same:
        ways = [f'{word} with {", ".join(n for up, n in same if up == rising)}'
                for rising, word in ((True, 'rising'), (False, 'falling'))
                if any(up == rising for up, _ in same)]
        opposite.insert(0, 'both ' + ' and '.join(ways))
    return opposite
