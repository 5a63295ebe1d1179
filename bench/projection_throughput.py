"""Wall time of the paper's grasping query (Table I: 6 forces x 3 positions) through the service.

For each number of simulation workers, starts a projection_server with an empty bag
directory (no cached projections), sends the query once in ALL_SOLUTIONS mode, and
repeats; prints the median wall time, the time per projection, and the speed-up.
Then sends the same query once more to the last node: every bag is cached.

    tools/with_env.sh python bench/projection_throughput.py --workers 1 2 --repeat 3
"""

from __future__ import annotations

import argparse
import os
import platform
import signal
import statistics
import subprocess
import sys
import tempfile
import time

QUERY = ('make_projection(grasping, grasp_object, '
         '[(P, position, [-0.02, 0.00, 0.02]), (F, force, [1, 3, 5, 7, 9, 11])], TL), '
         '( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip ; O = ok )')
PROJECTIONS = 18


def start_node(workers: int, bag_dir: str) -> subprocess.Popen:
    return subprocess.Popen(
        ['projection_server', '--ros-args', '-p', f'projection_workers:={workers}',
         '-p', f'bag_dir:={bag_dir}', '-p', 'default_timeout:=600.0'],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


def stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)


def timed_query(client) -> tuple[float, list]:
    start = time.perf_counter()
    solutions = client.all(QUERY, timeout=600.0)
    return time.perf_counter() - start, solutions


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--workers', type=int, nargs='+', default=[1, 2])
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', str(130 + os.getpid() % 30))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

    import rclpy
    from projection_server.client import PrologClient
    rclpy.init()
    medians: dict[int, float] = {}
    cached = None
    grid = None
    try:
        for workers in args.workers:
            times = []
            for r in range(args.repeat):
                with tempfile.TemporaryDirectory() as bag_dir:
                    proc = start_node(workers, bag_dir)
                    try:
                        with PrologClient(service_timeout=60.0) as client:
                            if not client.wait_for_server(60.0):
                                raise RuntimeError('the node did not come up')
                            client.once('true')   # the node is up and Prolog loaded
                            elapsed, grid = timed_query(client)
                            times.append(elapsed)
                            if workers == args.workers[-1] and r == args.repeat - 1:
                                cached, _ = timed_query(client)
                    finally:
                        stop(proc)
            medians[workers] = statistics.median(times)
            print(f'  workers={workers}: runs {", ".join(f"{t:.2f}" for t in times)} s')
    finally:
        rclpy.try_shutdown()

    print('projection throughput benchmark (Table I grasping query)')
    print(f'  settings: {PROJECTIONS} projections, ALL_SOLUTIONS, repeat={args.repeat} per '
          f'worker count, fresh bag_dir each run, physics from config/physics.yaml, '
          f'python {platform.python_version()}, {os.cpu_count()} cores')
    base = medians[args.workers[0]]
    for workers, med in medians.items():
        print(f'  workers={workers}: median {med:6.2f} s  ({med / PROJECTIONS * 1e3:6.0f} ms per '
              f'projection, speed-up {base / med:4.2f}x)')
    if cached is not None:
        print(f'  all 18 cached: {cached:6.2f} s')
    if grid:
        rows = {}
        for s in grid:
            rows.setdefault(s['P'], []).append(str(s['O']))
        for p, outcomes in rows.items():
            print(f'  position {p:+.2f}: ' + ' '.join(f'{o:5s}' for o in outcomes))
    return 0


if __name__ == '__main__':
    sys.exit(main())
