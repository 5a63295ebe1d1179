"""A 1,000-parametrization INCREMENTAL query through the service, in flat memory.

Starts a projection_server (``--workers`` workers, an empty bag directory, the node's
default retention of 1,000 bags) and opens one INCREMENTAL query over 1,000 grasps (force
1.00 to 10.99 N in steps of 0.01 N, at the centre), then takes every solution with
``~/next_solution``, as a client that backtracks through a large parameter space does.
Every ``--every`` solutions it samples the resident memory of the node and of each
worker, and the time per solution since the last sample.

The projections are cheap on purpose: each is a full projection (world, grasp program,
egg model, monitor, MCAP bag, timeline, Prolog), but with coarse physics chosen by the
query (``physics(_{rate_hz: 60, solver_iterations: 10})``: 228 steps instead of 912 at
100 iterations), so that 1,000 of them take minutes, not a quarter of an hour. None is
cached: every solution is a new bag. What grows with the number of projections is the
service's state (requests, timelines in Prolog, the bag directory and its index, the
workers' PyBullet worlds), not the cost of a projection's physics.

    tools/with_env.sh python bench/flat_memory.py --workers 2
"""

from __future__ import annotations

import os
from pathlib import Path
import platform
import statistics
import sys
import tempfile
import time

import harness

MANY = ('make_projection(grasping, grasp_object, '
        '[(F, force, range(1.0, 10.99, 0.01)), (P, position, [0.0])], '
        '[physics(_{rate_hz: 60, solver_iterations: 10})], TL), '
        '( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip ; O = ok )')
PARAMETRIZATIONS = 1000


def main() -> int:
    parser = harness.arguments(__doc__)
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--solutions', type=int, default=PARAMETRIZATIONS,
                        help='solutions to take (at most 1,000)')
    parser.add_argument('--every', type=int, default=50, help='solutions between samples')
    args = parser.parse_args()
    harness.ros_domain(130)

    import rclpy

    rclpy.init()
    rows: list[tuple[int, float, float, float, float]] = []
    outcomes: dict[str, int] = {}
    loads = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            bag_dir = Path(tmp) / 'bags'
            params = {'projection_workers': args.workers, 'bag_dir': str(bag_dir),
                      'default_timeout': 600.0, 'max_solutions': 2000}
            with harness.start_node(params, Path(tmp) / 'node.log') as proc, \
                    harness.client() as c:
                pid = proc.proc.pid
                rows.append((0, *memory(pid), 0.0, 0.0))
                start = last = time.perf_counter()
                with c.query(MANY, timeout=600.0) as stream:
                    for n, solution in enumerate(stream, start=1):
                        outcome = str(solution['O'])
                        outcomes[outcome] = outcomes.get(outcome, 0) + 1
                        if n % args.every == 0 or n == args.solutions:
                            now = time.perf_counter()
                            per = (now - last) / (n - rows[-1][0])
                            last = now
                            bags = sum(1 for _ in bag_dir.iterdir())
                            rows.append((n, *memory(pid), per, bags))
                            loads.append(os.getloadavg()[0])
                            print(f'  {n:4d} solutions: node {rows[-1][1]:5.1f} MB, '
                                  f'largest worker {rows[-1][2]:5.1f} MB, '
                                  f'{per * 1e3:4.0f} ms per solution, {bags} bags', flush=True)
                        if n >= args.solutions:
                            break
                elapsed = time.perf_counter() - start
    finally:
        rclpy.try_shutdown()
    report(args, rows, outcomes, elapsed, loads)
    return 0


def memory(pid: int) -> tuple[float, float]:
    """RSS of the node ``pid`` and of its largest worker [MB]."""
    return harness.rss_mb(pid), max(map(harness.rss_mb, harness.worker_pids(pid)), default=0.0)


def slope(points: list[tuple[float, float]]) -> float:
    """Least-squares slope of (x, y) points."""
    mx = statistics.fmean(x for x, _ in points)
    my = statistics.fmean(y for _, y in points)
    den = sum((x - mx) ** 2 for x, _ in points)
    return sum((x - mx) * (y - my) for x, y in points) / den if den else 0.0


def report(args, rows, outcomes, elapsed, loads) -> None:
    taken = rows[-1][0]
    sampled = rows[1:]
    second_half = [r for r in sampled if r[0] > taken / 2]
    node_mb = [r[1] for r in sampled]
    worker_mb = [r[2] for r in sampled]
    print('flat memory benchmark (one INCREMENTAL query over 1,000 grasps through the service)')
    print(f'  settings: {args.workers} workers, an empty bag directory, retention 1,000 bags; '
          f'rate_hz 60, 10 solver iterations (chosen by the query); python '
          f'{platform.python_version()}, {os.cpu_count()} cores, load average '
          f'{min(loads, default=0):.1f}-{max(loads, default=0):.1f}')
    print(f'  {taken} solutions in {elapsed:.1f} s ({elapsed / taken * 1e3:.0f} ms each); '
          f'outcomes {dict(sorted(outcomes.items()))}')
    print(f'  node RSS: {rows[0][1]:.1f} MB before the query, {min(node_mb):.1f}-'
          f'{max(node_mb):.1f} MB during it, last {node_mb[-1]:.1f} MB; second half slope '
          f'{slope([(r[0], r[1]) for r in second_half]) * 100:+.2f} MB per 100 solutions')
    print(f'  largest worker RSS: {min(worker_mb):.1f}-{max(worker_mb):.1f} MB (a worker is '
          f'replaced after 200 projections); second half slope '
          f'{slope([(r[0], r[2]) for r in second_half]) * 100:+.2f} MB per 100 solutions')
    first = [r[3] for r in sampled[:len(sampled) // 2]]
    later = [r[3] for r in second_half]
    print(f'  time per solution: median {statistics.median(first) * 1e3:.0f} ms in the first '
          f'half, {statistics.median(later) * 1e3:.0f} ms in the second')


if __name__ == '__main__':
    sys.exit(main())
