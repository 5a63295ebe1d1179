"""Convergence of the paper's three experiments: each at the programs' physics settings and
again at a 4x finer time step with 4x the solver iterations, through the live service.

Starts a projection_server with an empty bag directory (nothing cached; the default and
the reference runs have different cache keys anyway), runs Tables I, II and III (generic
pancake) both ways, and prints per table the cells that agree with the reference, the
cells that agree with the paper, the largest deviation of Table II's particle counts, and
the wall times (the reference's is what fidelity costs):

    tools/with_env.sh python bench/fidelity.py                  # all three, full grids
    tools/with_env.sh python bench/fidelity.py --only table2 --quick
"""

from __future__ import annotations

from pathlib import Path
import sys
import tempfile
import time

import harness

GOALS = {'table1': 'Table I >= 16/18 outcomes equal', 'table2': 'counts within 15 %',
         'table3': 'Table III 6/6 outcomes equal'}


def main() -> int:
    parser = harness.arguments(__doc__)
    parser.add_argument('--only', action='append', metavar='TABLE',
                        help='table1, table2 or table3 (repeatable; default: all three)')
    parser.add_argument('--quick', action='store_true', help='the reduced grids')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--timeout', type=float, default=1800.0,
                        help='seconds one projection may take (the reference is slow)')
    args = parser.parse_args()
    harness.ros_domain(140, 40)

    import rclpy

    from projection_server.reproduce.experiments import (compare, run_experiment,
                                                         TABLE_I_GRASPING, TABLE_II_POURING,
                                                         TABLE_III_TURNING)
    from projection_server.reproduce.fidelity import converged, reference_physics

    experiments = [e for e in (TABLE_I_GRASPING, TABLE_II_POURING, TABLE_III_TURNING)
                   if not args.only or e.key in args.only]
    lines = []
    rclpy.init()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            bag_dir = Path(tmp) / 'bags'
            bag_dir.mkdir()
            params = {'bag_dir': bag_dir, 'projection_workers': args.workers,
                      'default_timeout': args.timeout}
            with harness.start_node(params, Path(tmp) / 'node.log', stop_timeout=20.0), \
                    harness.client() as client:
                for exp in experiments:
                    physics = reference_physics(client, exp.program)
                    start = time.monotonic()
                    result = run_experiment(client, exp, quick=args.quick,
                                            timeout=args.timeout)
                    middle = time.monotonic()
                    reference = run_experiment(client, exp, quick=args.quick,
                                               timeout=args.timeout, physics=physics)
                    end = time.monotonic()
                    c = converged(result, reference)
                    lines += [f'{exp.title}',
                              f'  reference: {c.summary()}',
                              f'  goal: {GOALS[exp.key]}',
                              f'  paper: {compare(result).summary(limit=3)}',
                              f'  paper (reference): {compare(reference).summary(limit=0)}',
                              f'  wall time: {middle - start:.1f} s at the programs\' '
                              f'settings, {end - middle:.1f} s at the reference '
                              f'({(end - middle) / max(middle - start, 1e-9):.1f}x)']
                    if not exp.qualitative:
                        lines += _deviations(result, reference)
    finally:
        rclpy.try_shutdown()
    print()
    print('fidelity benchmark: the experiments at the programs\' settings vs a 4x finer '
          'reference (4x rate, 4x solver iterations)')
    print(f'  settings: {args.workers} workers, fresh bag_dir, '
          f'{"quick" if args.quick else "full"} grids, {harness.machine()} at the end')
    for line in lines:
        print('  ' + line)
    return 0


def _deviations(result, reference) -> list[str]:
    """Table II: ours vs the reference, per run, for the counts and the roundness."""
    theirs = reference.by_key()
    out = ['  deviations (ours - reference): pan, spill, roundness']
    for run in result.runs:
        ref = theirs.get(run.key)
        if ref is None:
            continue
        cells = []
        for column in ('pan', 'spill', 'round'):
            a, b = run.value.get(column), ref.value.get(column)
            cells.append('—' if a is None or b is None
                         else f'{a - b:+.0f}' if column != 'round' else f'{a - b:+.2f}')
        out.append(f'    {result.experiment.describe(run.key)}: ' + ', '.join(cells)
                   + f'  (reference pan {ref.value.get("pan")})')
    return out


if __name__ == '__main__':
    sys.exit(main())
