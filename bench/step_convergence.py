"""Table I and Table III at the default time step and at 2x and 4x finer ones, in-process.

Runs the knowledge base's grasping and turning scenarios (from the server's Prolog) with
``grasp_object`` over Table I's forces and positions and ``turn_pancake`` over Table III's
angles, each at ``rate_hz`` x1, x2 and x4 (``Settings.for_projection``, what a query's
``physics`` option does; solver iterations as configured, or with ``--iterations scaled``
x1, x2, x4 the program's own as bench/fidelity.py's reference has them), in two
processes, and prints the outcome grids, the cells that agree with the default step, those
that agree with the paper, and the median wall time per projection at each step:

    tools/with_env.sh python bench/step_convergence.py [--only table1|table3] [--factors 1,2,4]

``--only grip`` instead finds, at each step, the egg friction below which a grasp of
``--force`` newtons loses the egg (bisection over the KB egg's ``friction``): where a
grasp's outcome lies near that boundary, the boundary's drift with the step says whether
the finer answer is converged (it is when x4 and x8 find the same friction):

    tools/with_env.sh python bench/step_convergence.py --only grip --factors 1,2,4,8
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
import statistics
import tempfile
import time

import harness


def outcome(job: tuple) -> tuple[tuple, str, float]:
    """Run one projection; its Table I or III outcome and wall time."""
    from projection_server.simulation import Job, load_settings
    from projection_server.workers.run import run_projection
    from projection_server.workers.run import translate_bag

    scenario, program, params, factor, *scaled = job
    base = load_settings()
    physics = {'rate_hz': base.physics.rate_hz * factor}
    if scaled and scaled[0]:
        physics['solver_iterations'] = (
            base.for_projection(program).physics.solver_iterations * factor)
    settings = base.for_projection(program, physics)
    bag = Path(tempfile.mkdtemp(prefix='convergence-')) / 'bag'
    start = time.perf_counter()
    run_projection(Job.checked(scenario, program, params), settings, bag)
    elapsed = time.perf_counter() - start
    timeline = translate_bag(bag)
    if program == 'turn_pancake':
        result = 'ok' if any(f[0] == 'upside_down' for f in timeline['fluents']) else 'fail'
    else:
        result = harness.grasp_outcome(timeline)
    return (program, tuple(sorted(params.items())), factor), result, elapsed


def grip_boundary(job: tuple) -> tuple[int, float, float, list]:
    """The friction of the egg between a lost and a held grasp of ``force`` at the centre,
    at ``factor`` times the default rate, within ``tolerance``; and the runs it took."""
    scenario, force, factor, low, high, tolerance = job
    egg = next(e for e in scenario['entities'] if e['name'] == 'egg1')
    runs = []
    while high - low > tolerance:
        middle = round((low + high) / 2, 5)
        egg['properties']['friction'] = middle
        _, result, elapsed = outcome((scenario, 'grasp_object',
                                      {'force': force, 'position': 0.0}, factor))
        runs.append((middle, result, elapsed))
        if result == 'slip':
            low = middle
        else:
            high = middle
    return factor, low, high, runs


def main_grip(force: float, factors: list[int]) -> None:
    scenario = harness.kb_scenario('grasping')
    jobs = [(scenario, force, f, 0.1, 0.4, 0.0025) for f in factors]
    with ProcessPoolExecutor(2) as pool:
        found = list(pool.map(grip_boundary, jobs))
    print(f'grip: grasp_object(force {force}, position 0), egg friction bisected in '
          f'[0.1, 0.4] to 0.0025, rate x{factors}')
    for factor, low, high, runs in found:
        wall = statistics.median(r[2] for r in runs)
        shown = ', '.join(f'{m:.4f} {r}' for m, r, _ in runs)
        print(f'  x{factor}: lost below {low:.4f}, held from {high:.4f} '
              f'(median {wall:.2f} s per grasp; {shown})')


def main() -> None:
    from projection_server.reproduce import paper

    parser = harness.arguments(__doc__)
    parser.add_argument('--only', choices=['table1', 'table3', 'grip'])
    parser.add_argument('--factors', default='1,2,4')
    parser.add_argument('--iterations', choices=['fixed', 'scaled'], default='fixed',
                        help='solver iterations as configured, or times the rate factor')
    parser.add_argument('--force', type=float, default=3.0, help='N, for --only grip')
    args = parser.parse_args()
    factors = [int(f) for f in args.factors.split(',')]
    if args.only == 'grip':
        main_grip(args.force, factors)
        return
    tables = {
        'table1': ('grasping', 'grasp_object',
                   [{'force': float(f), 'position': p} for p in paper.GRASP_POSITIONS
                    for f in paper.GRASP_FORCES],
                   lambda q: paper.TABLE_I[(int(q['force']), q['position'])]),
        'table3': ('turning', 'turn_pancake', [{'angle': a} for a in paper.TURN_ANGLES],
                   lambda q: paper.TABLE_III[(q['angle'],)]),
    }
    for key, (scenario_name, program, cells, expected) in tables.items():
        if args.only and key != args.only:
            continue
        scenario = harness.kb_scenario(scenario_name)
        jobs = [(scenario, program, cell, factor, args.iterations == 'scaled')
                for factor in factors for cell in cells]
        with ProcessPoolExecutor(2) as pool:
            results = {k: (r, t) for k, r, t in pool.map(outcome, jobs)}
        print(f'{key}: {program}, {len(cells)} cells, rate x{factors}, '
              f'solver iterations {args.iterations}')
        grid = {f: [results[(program, tuple(sorted(c.items())), f)][0] for c in cells]
                for f in factors}
        for f in factors:
            same = sum(a == b for a, b in zip(grid[f], grid[factors[0]]))
            paper_ = sum(r == expected(c) for r, c in zip(grid[f], cells))
            wall = statistics.median(results[(program, tuple(sorted(c.items())), f)][1]
                                     for c in cells)
            print(f'  x{f}: {" ".join(f"{r:5}" for r in grid[f])}')
            print(f'      agree with x{factors[0]}: {same}/{len(cells)}, with the paper: '
                  f'{paper_}/{len(cells)}, median {wall:.2f} s per projection')


if __name__ == '__main__':
    main()
