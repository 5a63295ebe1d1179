"""The results beside the paper's: terminal tables, coloured grids, ``report.md``.

    >>> print(format_table(result))             # the paper's layout, paper / ours
    >>> write_report([result, ...], Path('out'))   # report.md + PNG files
"""

from __future__ import annotations

import math
from pathlib import Path
import re
from typing import Any, TYPE_CHECKING

from projection_server.reproduce.experiments import compare
from projection_server.reproduce.explain import explain

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from projection_server.reproduce.experiments import Experiment, Result

__all__ = ['OUTCOME_COLORS', 'format_table', 'grid_png', 'markdown_table', 'write_report']

OUTCOME_COLORS = {'ok': '#4caf50', 'slip': '#ff9800', 'break': '#e53935', 'fail': '#e53935'}
MISSING_COLOR = '#d0d0d0'


def format_table(result: Result) -> str:
    """The experiment's table in the paper's layout, each cell ``paper/ours`` (``*``: differs),
    followed by the agreement line and the line on why the cells differ."""
    exp = result.experiment
    if result.skipped:
        return f'{exp.title}: skipped: {result.skipped}'
    lines = [f'{exp.title}  (paper/ours, * = differs'
             + ('; quick grid)' if result.quick else ')')]
    lines += _qualitative_lines(result) if exp.qualitative else _quantitative_lines(result)
    if result.error:
        lines.append(f'stopped early: {result.error}')
    lines.append(compare(result).summary())
    lines.append(f'why: {explain(result)}')
    return '\n'.join(lines)


def grid_png(result: Result, path: str | Path) -> Path:
    """Paper and ours side by side as coloured grids (ok green, slip orange, break red)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    exp = result.experiment
    rows, cols = _layout(result)
    ours = result.by_key()
    fig, axes = plt.subplots(1, 2, figsize=(2.0 + 1.6 * len(cols), 1.4 + 0.55 * len(rows)),
                             squeeze=False)
    for ax, (label, value_of) in zip(axes[0], (
            ('paper', lambda key: exp.paper.get(key)),
            ('ours', lambda key: ours[key].value if key in ours else None))):
        for i, row in enumerate(rows):
            for j, col in enumerate(cols):
                key = _key(exp, row, col)
                value = value_of(key)
                color = OUTCOME_COLORS.get(value, MISSING_COLOR) if value else MISSING_COLOR
                ax.add_patch(Rectangle((j, i), 1, 1, facecolor=color, edgecolor='white',
                                       linewidth=2))
                ax.text(j + 0.5, i + 0.5, value or '—', ha='center', va='center',
                        fontsize=9, color='black')
        ax.set_xlim(0, len(cols))
        ax.set_ylim(len(rows), 0)
        ax.set_xticks([j + 0.5 for j in range(len(cols))], [c[1] for c in cols])
        ax.set_yticks([i + 0.5 for i in range(len(rows))], [r[1] for r in rows])
        ax.tick_params(length=0)
        for spine in ax.spines.values():
            spine.set_visible(False)
        ax.set_title(label)
        ax.set_xlabel(exp.cols or '')
        ax.set_ylabel(exp.rows or '')
    fig.suptitle(exp.title + (' (quick grid)' if result.quick else ''), fontsize=11)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def markdown_table(result: Result) -> str:
    """A Markdown table of the runs: parameters, then ``paper / ours`` per column."""
    exp = result.experiment
    if exp.qualitative:
        rows, cols = _layout(result)
        head = [exp.rows or '', *(c[1] for c in cols)]
        lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
        ours = result.by_key()
        for row in rows:
            cells = []
            for col in cols:
                key = _key(exp, row, col)
                mine = ours[key].value if key in ours else None
                cells.append(_pair(exp.paper.get(key), mine))
            lines.append(f'| {row[1]} | ' + ' | '.join(cells) + ' |')
        return '\n'.join(lines)
    head = [p.name for p in exp.params] + [m.column for m in exp.measures]
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for run in result.runs:
        theirs = exp.paper.get(run.key, {})
        cells = [p.show(v) for p, v in zip(exp.params, run.key)]
        cells += [_pair(theirs.get(m.column), run.value.get(m.column), m.tolerance)
                  for m in exp.measures]
        lines.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def write_report(results: Sequence[Result], out: str | Path, *, frames: bool = True,
                 log: Callable[[str], None] = print) -> Path:
    """Write ``out/report.md`` with grids, tables and key frames; return its path."""
    from projection_server.reproduce import render

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    md = ['# Reproduction of Kunze, Dolha & Beetz (IROS 2011), section IV', '',
          'Each experiment ran as the paper\'s query through the live query service; '
          'cells read `paper / ours` (**bold**: they differ).', '']
    for result in results:
        exp = result.experiment
        md += [f'## {exp.title}', '']
        if result.skipped:
            md += [f'Skipped: {result.skipped}.', '']
            continue
        md += ['```', exp.query(result.quick), '```', '',
               f'{len(result.runs)} projections in {result.elapsed:.1f} s'
               + (' (quick grid)' if result.quick else '') + '. '
               + f'**{compare(result).summary()}**', '',
               f'Why: {explain(result)}.', '']
        if result.error:
            md += [f'Stopped early: `{result.error}`', '']
        if exp.qualitative and result.runs:
            png = grid_png(result, out / f'{exp.key}_grid.png')
            md += [f'![{exp.title}]({png.name})', '']
        md += [markdown_table(result), '']
        if frames:
            md += _frames_section(result, out, render, log)
    path = out / 'report.md'
    path.write_text('\n'.join(md) + '\n')
    return path


# -- internals -----------------------------------------------------------------------------

def _frames_section(result: Result, out: Path, render: Any,
                    log: Callable[[str], None]) -> list[str]:
    md = []
    for showcase in result.experiment.showcases:
        run = result.find(showcase.params)
        if run is None:
            continue
        name = re.sub(r'[^A-Za-z0-9_.-]+', '_',
                      f'{result.experiment.key}_frames_{result.experiment.describe(run.key)}')
        try:
            scene = render.BagScene.load(run.bag)
            times = render.key_times(run.events, run.duration)
            png = render.render_strip(scene, times, out / f'{name}.png',
                                      caption=showcase.caption, target=showcase.target)
        except render.RenderError as exc:
            log(f'  no key frames for {showcase.caption}: {exc}')
            continue
        events = ', '.join(f'{e.term} at {e.start:.2f} s' for e in run.events) or 'none'
        md += [f'### {showcase.caption}', '',
               f'{result.experiment.describe(run.key)}; outcome {_text(run.value)}; '
               f'events: {events}. Rendered from the bag `{run.bag}`.', '',
               f'![{showcase.caption}]({png.name})', '']
    return md


def _layout(result: Result) -> tuple[list[tuple[float, str]], list[tuple[float, str]]]:
    """Row and column headings (value, label) of a qualitative table: the grid that ran."""
    exp = result.experiment
    by_name = {p.name: p for p in exp.params}
    col = by_name[exp.cols]
    cols = [(v, col.show(v)) for v in col.grid(result.quick)]
    if exp.rows is None:
        return [(None, col.name)], cols
    row = by_name[exp.rows]
    return [(v, row.show(v)) for v in row.grid(result.quick)], cols


def _key(exp: Experiment, row: tuple, col: tuple) -> tuple:
    values = {exp.cols: col[0]}
    if exp.rows is not None:
        values[exp.rows] = row[0]
    return tuple(values[p.name] for p in exp.params)


def _qualitative_lines(result: Result) -> list[str]:
    exp = result.experiment
    rows, cols = _layout(result)
    ours = result.by_key()
    table = [[exp.rows or '', *(c[1] for c in cols)]]
    for row in rows:
        cells = [row[1]]
        for col in cols:
            key = _key(exp, row, col)
            theirs = exp.paper.get(key)
            mine = ours[key].value if key in ours else None
            mark = '*' if key in ours and theirs is not None and theirs != mine else ''
            cells.append(f'{_text(theirs)}/{_text(mine)}{mark}')
        table.append(cells)
    return _columns(table)


def _quantitative_lines(result: Result) -> list[str]:
    exp = result.experiment
    table = [[p.name for p in exp.params] + [m.column for m in exp.measures]]
    for run in result.runs:
        theirs = exp.paper.get(run.key, {})
        cells = [p.show(v) for p, v in zip(exp.params, run.key)]
        for m in exp.measures:
            paper_value, mine = theirs.get(m.column), run.value.get(m.column)
            differs = not _agrees(paper_value, mine, m.tolerance)
            cells.append(f'{_text(paper_value)}/{_text(mine)}' + ('*' if differs else ''))
        table.append(cells)
    return _columns(table)


def _columns(table: list[list[str]]) -> list[str]:
    widths = [max(len(row[i]) for row in table) for i in range(len(table[0]))]
    return ['  '.join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip()
            for row in table]


def _agrees(theirs: Any, ours: Any, tolerance: Any) -> bool:
    if theirs is None or ours is None:
        return theirs is None and ours is None
    if tolerance is None or isinstance(theirs, str):
        return theirs == ours
    return abs(float(ours) - float(theirs)) <= tolerance(float(theirs)) + 1e-12


def _pair(theirs: Any, ours: Any, tolerance: Any = None) -> str:
    text = f'{_text(theirs)} / {_text(ours)}'
    return text if _agrees(theirs, ours, tolerance) else f'**{text}**'


def _text(value: Any) -> str:
    if value is None:
        return '—'
    if isinstance(value, float):
        if math.isfinite(value) and value == int(value) and abs(value) >= 1:
            return str(int(value))
        return f'{value:.3f}'
    return str(value)
