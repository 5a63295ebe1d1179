"""The batter's fit to the paper's Table II: pan counts of the 27 pours for candidate values of
the mix's properties, in this process's workers (no node), against the paper's.

    tools/with_env.sh python bench/batter_fit.py --set surface_tension=0.5,1,2
    tools/with_env.sh python bench/batter_fit.py --set surface_tension=1 --set viscosity=20 \\
        --angles 1.84
    tools/with_env.sh python bench/batter_fit.py --set surface_tension=0.25,0.4 --tilt-rate 1,2

Each ``--set NAME=V1,V2,..`` is a property of ``pancake_mix1`` (``ENTITY.NAME``: of another
entity of the scenario, e.g. ``cup1.friction``) and its candidate values; every
combination of the candidates (and of ``--tilt-rate``'s rates of the pour, its
second coefficient) runs the pours of ``--angles`` (default: all three) at the
paper's positions and times, at the pour's own physics, in ``--workers`` processes. Printed
per combination: the pan counts beside the paper's, how many are within 2x of the paper's (a
count of at most 2 particles counts as 2), the Spearman correlation of the pan counts with the
paper's, how many of the table's cells (5 measures a pour) agree with the paper's by
``make reproduce``'s tolerances, and the CPU seconds of the pours.
"""

from __future__ import annotations

import itertools
from multiprocessing import get_context
from pathlib import Path
import tempfile
import time

import numpy as np

import harness


# Table II's columns and the quantities that measure them.
COLUMNS = {'pan': 'particles_on', 'spill': 'particles_spilled', 'off_x': 'centroid_offset_x',
           'off_y': 'centroid_offset_y', 'round': 'roundness'}


def within_2x(ours: float, theirs: float) -> bool:
    """Within a factor of 2 of the paper's count, counts of at most 2 taken as 2."""
    a, b = max(ours, 2.0), max(theirs, 2.0)
    return b / 2 <= a <= 2 * b


def spearman(a: list[float], b: list[float]) -> float:
    def ranks(x):
        x = np.asarray(x, dtype=float)
        order = x.argsort(kind='stable')
        r = np.empty(len(x))
        r[order] = np.arange(len(x))
        for v in np.unique(x):   # ties: their mean rank
            r[x == v] = r[x == v].mean()
        return r
    return float(np.corrcoef(ranks(a), ranks(b))[0, 1])


def _pour(args):
    scenario, params, physics, *rate = args
    from projection_server.settings import load_settings
    from projection_server.simulation.programs import pour

    if rate and rate[0] is not None:   # the pour's tilt rate, the fit's second coefficient
        pour.TILT_RATE = rate[0]
    from projection_server.simulation import Job
    from projection_server.workers.run import run_projection

    job = Job.checked(scenario, 'pour', params)
    settings = load_settings().for_projection('pour', physics)
    start = time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        timeline = run_projection(job, settings, Path(tmp) / 'bag')
    cpu = time.process_time() - start
    values = {name: value for name, args_, value in timeline['quantities']
              if args_ in (['pancake_maker1'], ['pancake_mix1'])}
    measures = {column: values.get(name) for column, name in COLUMNS.items()}
    measures['positions'] = values.get('particles_on_positions')
    return measures, cpu


def main() -> int:
    parser = harness.arguments(__doc__)
    parser.add_argument('--set', action='append', default=[],
                        help='[ENTITY.]NAME=V1,V2,...: candidate values of a property of the '
                             'mix (or of ENTITY)')
    parser.add_argument('--angles', default='1.84,1.99,2.14')
    parser.add_argument('--tilt-rate', default=None,
                        help='R1,R2,...: candidate tilt rates of the pour [rad/s] (default: '
                             "the program's)")
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--physics', default='{}', help='settings over the pour\'s (JSON)')
    parser.add_argument('--save', default=None,
                        help='FILE: every pour\'s measures and pan positions, as JSON lines')
    args = parser.parse_args()
    import json

    from projection_server.reproduce import paper
    from projection_server.reproduce.experiments import _cell_agrees, _show, TABLE_II_POURING

    physics = json.loads(args.physics)
    angles = [float(a) for a in args.angles.split(',')]
    names, candidates = [], []
    for item in args.set:
        name, values = item.split('=')
        names.append(name)
        candidates.append([float(v) for v in values.split(',')])
    cells = [(p, t, a) for p in paper.POUR_POSITIONS for t in paper.POUR_TIMES
             for a in angles]
    print(f'batter fit: {len(cells)} pours per combination, angles {angles}, '
          f'physics {physics or "of the pour"}; {harness.machine()}', flush=True)
    rates = [float(r) for r in args.tilt_rate.split(',')] if args.tilt_rate else [None]
    with get_context('forkserver').Pool(args.workers) as pool:
        for rate, combination in itertools.product(rates, itertools.product(*candidates)):
            scenario = harness.kb_scenario('pouring')
            harness.set_properties(scenario['entities'], dict(zip(names, combination)))
            start = time.monotonic()
            results = pool.map(_pour, [(scenario, {'position': p, 'time': t, 'angle': a},
                                        physics, rate) for p, t, a in cells])
            wall = time.monotonic() - start
            if args.save:
                with open(args.save, 'a') as out:
                    for c, r in zip(cells, results):
                        out.write(json.dumps({'set': dict(zip(names, combination)),
                                              'rate': rate, 'cell': c, 'cpu': r[1],
                                              **r[0]}) + '\n')
            ours = [r[0]['pan'] or 0 for r in results]
            theirs = [paper.TABLE_II[c]['pan'] for c in cells]
            good = sum(within_2x(o, t) for o, t in zip(ours, theirs))
            agree = sum(_cell_agrees(m, paper.TABLE_II[c][m.column], r[0][m.column])
                        for c, r in zip(cells, results) for m in TABLE_II_POURING.measures)
            print(f'\n{dict(zip(names, combination)) or "the mix of the knowledge base"}'
                  f'{"" if rate is None else f", tilt rate {rate} rad/s"}: '
                  f'{good}/{len(cells)} pan counts within 2x, Spearman '
                  f'{spearman(ours, theirs):.3f}, {agree}/{5 * len(cells)} cells agree; '
                  f'CPU {sum(r[1] for r in results):.1f} s, wall {wall:.1f} s', flush=True)
            by_column = {m.column: sum(_cell_agrees(m, paper.TABLE_II[c][m.column],
                                                    r[0][m.column])
                                       for c, r in zip(cells, results))
                         for m in TABLE_II_POURING.measures}
            print('  agree by measure: ' + ', '.join(f'{k} {v}/{len(cells)}'
                                                     for k, v in by_column.items()))
            for (p, t, a), o, th, r in zip(cells, ours, theirs, results):
                shown = ' '.join(
                    f'{m.column} {_show(r[0][m.column])} ({_show(paper.TABLE_II[(p, t, a)][m.column])})'
                    f'{"" if _cell_agrees(m, paper.TABLE_II[(p, t, a)][m.column], r[0][m.column]) else "*"}'
                    for m in TABLE_II_POURING.measures[1:])
                print(f'  {p:+.2f} m {t:.1f} s {a:.2f} rad: pan {o:4d} (paper {th:3d})'
                      f'{"" if within_2x(o, th) else "  x"} {shown}', flush=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
