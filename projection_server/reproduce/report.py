"""The results beside the paper's: terminal tables, coloured grids, ``report.md``.

    >>> print(format_table(result))             # the paper's layout, paper / ours
    >>> write_report([result, ...], Path('out'))   # report.md + PNG files
"""

from __future__ import annotations

import json
import math
from pathlib import Path
import re
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.reproduce.experiments import compare
from projection_server.reproduce.explain import explain
from projection_server.reproduce.fidelity import converged
from projection_server.errors import ProjectionError

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping, Sequence

    from projection_server.reproduce.experiments import Experiment, Result, Run

__all__ = ['OUTCOME_COLORS', 'format_table', 'grid_png', 'markdown_table', 'pca_png',
           'write_report']

OUTCOME_COLORS = {'ok': '#4caf50', 'slip': '#ff9800', 'break': '#e53935', 'fail': '#e53935'}
MISSING_COLOR = '#d0d0d0'


def format_table(result: Result, reference: Result | None = None) -> str:
    """The experiment's table in the paper's layout, each cell ``paper/ours`` (``*``: differs),
    followed by the agreement line (and that with a finer ``reference`` run of the same
    query) and the line on why the cells differ."""
    exp = result.experiment
    if result.skipped:
        return f'{exp.title}: skipped: {result.skipped}'
    lines = [f'{exp.title}  (paper/ours, * = differs'
             + ('; quick grid)' if result.quick else ')')]
    lines += _qualitative_lines(result) if exp.qualitative else _quantitative_lines(result)
    if result.error:
        lines.append(f'stopped early: {result.error}')
    lines.append(compare(result).summary())
    if reference is not None:
        lines.append(converged(result, reference).summary())
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
                 log: Callable[[str], None] = print,
                 references: Mapping[str, Result] | None = None) -> Path:
    """Write ``out/report.md`` with grids, tables and key frames; return its path.

    ``references`` maps an experiment's key to the same query run at finer physics
    settings: its agreement is shown beside the agreement with the paper."""
    from projection_server import render

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
               + f'**{compare(result).summary()}**', '']
        reference = (references or {}).get(exp.key)
        if reference is not None:
            md += [f'Convergence: **{converged(result, reference).summary()}** '
                   f'({len(reference.runs)} projections in {reference.elapsed:.1f} s).', '']
        md += [f'Why: {explain(result)}.', '']
        if result.error:
            md += [f'Stopped early: `{result.error}`', '']
        if exp.qualitative and result.runs:
            png = grid_png(result, out / f'{exp.key}_grid.png')
            md += [f'![{exp.title}]({png.name})', '']
        md += [markdown_table(result), '']
        md += _pca_section(result, out, log)
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


def _pca_section(result: Result, out: Path, log: Callable[[str], None]) -> list[str]:
    """The paper's Fig. 6 for our runs: the roundest and the least round configuration of
    particles on the pan (at least 10 of them), with their principal axes."""
    rounded = [r for r in result.runs if isinstance(r.value, dict)
               and isinstance(r.value.get('round'), (int, float))
               and isinstance(r.value.get('pan'), (int, float)) and r.value['pan'] >= 10]
    if len(rounded) < 2:
        return []
    chosen = [max(rounded, key=lambda r: r.value['round']),
              min(rounded, key=lambda r: r.value['round'])]
    try:
        png = pca_png(result.experiment, chosen, out / f'{result.experiment.key}_pca.png')
    except ProjectionError as exc:
        log(f'  no PCA plot: {exc}')
        return []
    return ['### PCA of particle configurations on the pancake maker (Fig. 6)', '',
            f'![PCA of particle configurations]({png.name})', '']


def pca_png(exp: Experiment, runs: Sequence[Run], path: str | Path) -> Path:
    """Fig. 6 for ``runs``: the on-pan particles of each run's bag (top view, relative to the
    pancake maker's centre) with their principal axes, two standard deviations long."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from projection_server.timeline import pouring
    from projection_server.workers.run import translate_bag

    from matplotlib.patches import Circle

    fig, axes = plt.subplots(1, len(runs), figsize=(3.6 * len(runs), 3.8), squeeze=False)
    for ax, run in zip(axes[0], runs):
        timeline = translate_bag(run.bag)
        points = next((q[2] for q in timeline['quantities']
                       if q[0] == 'particles_on_positions'), [])
        xy = np.asarray(points, dtype=float).reshape(-1, 3)[:, :2]
        pca = pouring.principal_axes(xy)
        if pca is None:
            continue
        centroid, eigenvalues, vectors = pca
        # The maker's centre: the centroid less the offset the timeline measured.
        centre = centroid - (run.value['off_x'], run.value['off_y'])
        rel = xy - centre
        ax.scatter(rel[:, 0], rel[:, 1], s=12, color='#d9a441', edgecolors='#8a6414',
                   linewidths=0.5)
        for value, vector, color in zip(eigenvalues[::-1], vectors.T[::-1], ('#c62828',
                                                                                '#1565c0')):
            half = 2.0 * math.sqrt(value) * vector
            ax.plot(*zip(centroid - centre - half, centroid - centre + half), color=color,
                    linewidth=2)
        ax.plot(0.0, 0.0, marker='+', color='black', markersize=10)
        radius = _maker_radius(run.bag)
        if radius:
            ax.add_patch(Circle((0.0, 0.0), radius, fill=False, color='#555555'))
            ax.set_xlim(-1.05 * radius, 1.05 * radius)
            ax.set_ylim(-1.05 * radius, 1.05 * radius)
        ax.set_aspect('equal')
        ax.set_xlabel('x [m]')
        ax.set_ylabel('y [m]')
        ax.set_title(f'{exp.describe(run.key)}\n{len(xy)} particles, roundness '
                     f'{run.value["round"]:.2f}', fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _maker_radius(bag: str) -> float | None:
    """The radius of the pancake maker in the scenario a bag recorded."""
    from projection_server.bags import read_bag, TOPICS

    for _, _, info in read_bag(bag, [TOPICS['info']]):
        for entity in json.loads(info.scenario_json)['entities']:
            if entity['class'] == 'pancake_maker':
                return float(entity['properties']['radius'])
    return None


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
