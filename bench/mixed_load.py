"""A short query while another client's long grid runs: how long the short one waits.

Starts its own node (2 workers, a fresh bag directory) and, once its workers are warm, sends
one client's Table II query (27 pours, all solutions) and, from a second client, a new egg
grasp every ``--every`` seconds while the pours run, each a ONCE query of one projection.
Prints the grasps' round trips during the grid against the same grasps on the idle node
before it, and the grid's own time::

    tools/with_env.sh python bench/mixed_load.py
    tools/with_env.sh python bench/mixed_load.py --grasps 5 --every 12
    tools/with_env.sh python bench/mixed_load.py --backend ray   # a private Ray instance
"""

from __future__ import annotations

import os
from pathlib import Path
import statistics
import sys
import tempfile
import threading
import time

import harness

GRID = ('make_projection(pouring, pour, [(P, position, [-0.09, 0.0, 0.07]), '
        '(T, time, [0.0, 0.5, 1.0]), (A, angle, [1.84, 1.99, 2.14])], TL)')


def grasp(force: float) -> str:
    return (f'make_projection(grasping, grasp_object, [(_, force, [{force}]), '
            '(_, position, [0.01])], TL)')


def main() -> int:
    parser = harness.arguments(__doc__)
    parser.add_argument('--grasps', type=int, default=5, help='grasps during the grid')
    parser.add_argument('--every', type=float, default=12.0, help='s between them')
    parser.add_argument('--backend', choices=('local', 'ray'), default='local')
    args = parser.parse_args()
    harness.ros_domain(130)

    import rclpy

    rclpy.init()
    with tempfile.TemporaryDirectory() as tmp:
        params = {'projection_workers': 2, 'bag_dir': os.path.join(tmp, 'bags'),
                  'default_timeout': 600.0, 'max_solutions': 2000,
                  'projection_backend': args.backend}
        # Ray and its actors start with the first projection: warmed below instead.
        with harness.start_node(params, Path(tmp) / 'node.log', warm=args.backend == 'local'):
            short, long_ = harness.client(), harness.client()
            forces = iter(2.0 + i / 100 for i in range(2 * args.grasps + 3))
            if args.backend == 'ray':
                assert short.once(grasp(next(forces)), timeout=600.0) is not None
                time.sleep(10.0)
            idle = []
            for _ in range(args.grasps):
                started = time.perf_counter()
                assert short.once(grasp(next(forces)), timeout=600.0) is not None
                idle.append(time.perf_counter() - started)
            grid: dict[str, float] = {}

            def run_grid() -> None:
                started = time.perf_counter()
                solutions = long_.all(GRID, timeout=600.0)
                grid['seconds'] = time.perf_counter() - started
                grid['solutions'] = len(solutions)

            thread = threading.Thread(target=run_grid)
            grid_start = time.perf_counter()
            thread.start()
            busy = []
            for i in range(args.grasps):
                time.sleep(max(0.0, grid_start + (i + 1) * args.every - time.perf_counter()))
                started = time.perf_counter()
                assert short.once(grasp(next(forces)), timeout=600.0) is not None
                busy.append(time.perf_counter() - started)
            thread.join()
            short.close()
            long_.close()
    rclpy.shutdown()
    print('mixed load benchmark: one-grasp ONCE queries from one client while another '
          "client's Table II grid (27 pours, ALL_SOLUTIONS) runs, against the idle node")
    print(f'  settings: {args.backend} backend, 2 workers, fresh bag_dir, {args.grasps} '
          f'grasps idle and {args.grasps} during the grid, one every {args.every:g} s from '
          f'its start; {harness.machine()} at the end')
    print(f'  grasp on the idle node: median {statistics.median(idle):.2f} s '
          f'({harness.listed(idle)})')
    print(f'  grasp during the grid:  median {statistics.median(busy):.2f} s, max '
          f'{max(busy):.2f} s ({harness.listed(busy)})')
    print(f'  the grid: {grid["solutions"]} solutions in {grid["seconds"]:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
