"""The ~/project action against the ~/query service, and how fast a cancelled goal stops.

1. Overhead of the action's per-projection feedback: the paper's Table I query (18
   projections, every bag cached after a first run) sent alternately through ~/query (the
   floor) and ~/project, ``--repeat`` times each; medians and their ratio.
2. Cancel latency: a query of uncached projections is sent to ~/project and cancelled
   after its first feedback, ``--cancels`` times; the time from the cancel request to the
   goal's result, and to the node's engine being free again (polled with ~/ping).

    tools/with_env.sh python bench/project_action.py --repeat 7 --cancels 5
"""

from __future__ import annotations

from pathlib import Path
import platform
import statistics
import sys
import tempfile
import time

import harness

TABLE_I = ('make_projection(grasping, grasp_object, '
           '[(F, force, [1, 3, 5, 7, 9, 11]), (P, position, [-0.02, 0.00, 0.02])], TL), '
           'not(occurs(break, _, TL)), not(occurs(slip, _, TL))')


def uncached(run: int) -> str:
    forces = ', '.join(f'{1.05 + 0.5 * k + 0.01 * run:.2f}' for k in range(8))
    return (f'make_projection(grasping, grasp_object, [(F, force, [{forces}]), '
            '(P, position, [0.0])], TL)')


def main() -> int:
    parser = harness.arguments(__doc__, repeat=7)
    parser.add_argument('--cancels', type=int, default=5)
    args = parser.parse_args()
    harness.ros_domain(160)

    import rclpy
    from projection_server.client import PrologQueryError

    rclpy.init()
    tmp = Path(tempfile.mkdtemp(prefix='bench_project_action_'))
    params = {'bag_dir': str(tmp / 'bags'), 'default_timeout': 600.0}
    print(f'# bench/project_action.py  {platform.node()}  {harness.machine()}')
    with harness.start_node(params, tmp / 'node.log'), harness.ServerStats() as stats:
        with harness.client(service_timeout=30.0) as client:
            client.all(TABLE_I, timeout=600.0)   # fills the bag cache
            service, action = [], []
            for _ in range(args.repeat):
                start = time.perf_counter()
                client.all(TABLE_I, timeout=600.0)
                service.append(time.perf_counter() - start)
                feedback = []
                start = time.perf_counter()
                client.project(TABLE_I, timeout=600.0,
                               feedback_callback=feedback.append).result()
                action.append(time.perf_counter() - start)
                assert len(feedback) == 18, len(feedback)
            s, a = statistics.median(service), statistics.median(action)
            print(f'Table I, 18 cached projections, {args.repeat} runs each:')
            print(f'  ~/query   median {s * 1e3:8.1f} ms   (floor)')
            print(f'  ~/project median {a * 1e3:8.1f} ms   18 feedback messages')
            print(f'  ratio project/query {a / s:.2f}')

            latencies, engines_after = [], []
            for run in range(args.cancels):
                task = client.project(uncached(run), timeout=600.0)
                while task.feedback() is None and not task.is_done():
                    time.sleep(0.01)
                start = time.perf_counter()
                task.cancel()
                try:
                    task.result()
                except PrologQueryError as exc:
                    assert exc.kind == 'cancelled', exc
                latencies.append(time.perf_counter() - start)
                while stats()['engines'] and time.perf_counter() - start < 30.0:
                    time.sleep(0.01)
                engines_after.append(time.perf_counter() - start)
            print(f'Cancel after the first feedback, {args.cancels} runs (projections of '
                  'about a second each):')
            print(f'  cancel -> result median {statistics.median(latencies) * 1e3:.0f} ms, '
                  f'max {max(latencies) * 1e3:.0f} ms')
            print(f'  cancel -> engine free median {statistics.median(engines_after) * 1e3:.0f}'
                  f' ms, max {max(engines_after) * 1e3:.0f} ms')
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
