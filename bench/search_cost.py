"""Table I's force boundaries by bisection (outcome_boundary/7) against the grid of the
same resolution: projections and seconds of each, in the same run.

At position 0.0 over 0.5-20 N, the grasp slips below about 1 N and breaks the egg above
about 10 N. The grid projects every 0.25 N (79 grasps) and reads the changes off its
neighbours; the bisection seeds with a coarse pass and halves each change's interval to
0.25 N. Each measurement gets a node of its own with an empty bag directory, so nothing
is cached; the two take turns, ``--repeat`` rounds; medians.

    tools/with_env.sh python bench/search_cost.py --repeat 3
"""

from __future__ import annotations

from pathlib import Path
import platform
import statistics
import sys
import tempfile
import time

import harness

OK = '( \\+ occurs(slip, _, TL), \\+ occurs(break, _, TL) )'
BISECTION = ('outcome_boundary(grasping, grasp_object, '
             '[(F, force, range(0.5, 20)), (P, position, [0.0])], '
             f'[tolerance({{tolerance}})], TL, {OK}, B)')
GRID = ('make_projection(grasping, grasp_object, '
        '[(F, force, range(0.5, 20.0, {tolerance})), (P, position, [0.0])], TL), '
        f'( {OK} -> Ok = true ; Ok = false )')


def measure(query: str, tmp: Path, name: str, workers: int) -> tuple[float, list[dict]]:
    """Seconds and solutions of ``query`` on a fresh node with its own empty bag dir."""
    params = {'bag_dir': str(tmp / name / 'bags'), 'default_timeout': 600.0,
              'projection_workers': workers}
    with harness.start_node(params, tmp / f'{name}.log'), \
            harness.client(service_timeout=30.0) as client:
        start = time.perf_counter()
        solutions = client.all(query, timeout=600.0, max_solutions=1000)
        return time.perf_counter() - start, solutions


def grid_changes(solutions: list[dict]) -> list[tuple[float, float]]:
    cells = [(s['F'], str(s['Ok']) == 'true') for s in solutions]
    return [(f1, f2) for (f1, o1), (f2, o2) in zip(cells, cells[1:]) if o1 != o2]


def boundary(solution: dict) -> dict:
    return {str(k): v for k, v in solution['B'].pairs}


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3)
    parser.add_argument('--tolerance', type=float, default=0.25)
    parser.add_argument('--workers', type=int, default=2)
    args = parser.parse_args()
    harness.ros_domain(190)

    import rclpy

    rclpy.init()
    tmp = Path(tempfile.mkdtemp(prefix='bench_search_cost_'))
    print(f'# bench/search_cost.py  {platform.node()}  {harness.machine()}')
    print(f'Table I at position 0.0, 0.5-20 N to {args.tolerance} N, '
          f'{args.workers} workers, {args.repeat} rounds, nothing cached')
    grid_s, bisect_s, ok = [], [], True
    for r in range(args.repeat):
        seconds, sols = measure(GRID.format(tolerance=args.tolerance), tmp, f'grid{r}',
                                args.workers)
        grid_s.append(seconds)
        grid_n, changes = len(sols), grid_changes(sols)
        seconds, sols = measure(BISECTION.format(tolerance=args.tolerance), tmp,
                                f'bisection{r}', args.workers)
        bisect_s.append(seconds)
        found = [boundary(s) for s in sols]
        bisect_n = sum(b['projections'] for b in found)
        agree = len(changes) == len(found) and all(
            max(f1, b['low']) <= min(f2, b['high']) and b['high'] - b['low'] <= args.tolerance
            for (f1, f2), b in zip(changes, found))
        ok = ok and agree
        print(f'  round {r + 1}: grid {grid_n} projections {grid_s[-1]:6.2f} s, changes '
              f'{changes}; bisection {bisect_n} projections {bisect_s[-1]:6.2f} s, '
              f'intervals {[(b["low"], b["high"]) for b in found]}; agree: {agree}')
    g, b = statistics.median(grid_s), statistics.median(bisect_s)
    print(f'grid      {grid_n:3d} projections  median {g:6.2f} s  ({harness.listed(grid_s)})')
    print(f'bisection {bisect_n:3d} projections  median {b:6.2f} s  '
          f'({harness.listed(bisect_s)})')
    print(f'grid/bisection: {grid_n / bisect_n:.1f}x the projections, {g / b:.1f}x the time')
    rclpy.try_shutdown()
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
