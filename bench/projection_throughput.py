"""Table I through the service against the bare physics of its 18 grasps, measured in the same run.

For each number of simulation workers, starts a projection_server with an empty bag
directory (no cached projections) and sends the paper's grasping query (6 forces x 3
positions) once in ALL_SOLUTIONS mode; repeats. In the same run, this process steps the
same 18 grasps bare (world, program, ``stepSimulation`` and the egg's contact query per
step; see ``bench/pipeline_overhead.py``): the floor of W workers is that sum divided by W.
It also steps them bare in W processes at once: on a machine shared with other work, that
wall time is the floor W workers can reach there and then.
On the last node it also measures:

* the first solution of an INCREMENTAL query over grasps not made yet, against the bare
  stepping of that one grasp;
* the cached re-query (the same Table I query again: every bag and timeline exists);
* the resident memory of the node and of each worker after Table I.

``--flat-memory N`` then opens an INCREMENTAL query over 1,000 parametrizations on a fresh
node, takes N solutions and prints the node's and the workers' memory every N/5 solutions.

    tools/with_env.sh python bench/projection_throughput.py --workers 1 2 --repeat 3
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import platform
import statistics
import sys
import tempfile
import time

from pipeline_overhead import floor, parallel_floor, scenario

POSITIONS = [-0.02, 0.00, 0.02]
FORCES = [1, 3, 5, 7, 9, 11]
QUERY = ('make_projection(grasping, grasp_object, '
         '[(P, position, [-0.02, 0.00, 0.02]), (F, force, [1, 3, 5, 7, 9, 11])], TL), '
         '( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip ; O = ok )')
PROJECTIONS = len(POSITIONS) * len(FORCES)
# Grasps that Table I does not make: the first solution needs a new projection.
FIRST = ('make_projection(grasping, grasp_object, [(F, force, [4, 6, 8]), '
         '(P, position, [0.01])], TL), ( occurs(break, _, TL) -> O = break ; O = ok )')
FIRST_PARAMS = {'force': 4, 'position': 0.01}
MANY = ('make_projection(grasping, grasp_object, '
        '[(F, force, range(1.0, 10.99, 0.01)), (P, position, [0.0])], TL), '
        '( occurs(break, _, TL) -> O = break ; O = ok )')


def rss_mb(pid: int) -> float:
    """Resident set size of a process [MB] (0 if it is gone)."""
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def children(pid: int) -> list[int]:
    out = []
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / 'stat').read_text()
            except OSError:
                continue
            if int(stat.rsplit(')', 1)[1].split()[1]) == pid:
                out.append(int(entry.name))
    return out


def worker_rss(pid: int) -> list[float]:
    """RSS of the node's projection workers [MB]: the children of its forkserver."""
    out = []
    for child in children(pid):
        try:
            cmdline = Path(f'/proc/{child}/cmdline').read_bytes()
        except OSError:
            continue
        if b'forkserver' in cmdline:
            out += [rss_mb(worker) for worker in children(child)]
    return out


def node(workers: int, bag_dir: str, log: Path):
    from projection_server.launcher import node_command, NodeProcess

    return NodeProcess(node_command('/projection_server', {
        'projection_workers': workers, 'bag_dir': bag_dir, 'default_timeout': 600.0,
        'max_solutions': 2000}), log)


def client():
    from projection_server.client import PrologClient

    c = PrologClient(service_timeout=60.0)
    if not c.wait_for_server(60.0):
        raise RuntimeError('the node did not come up')
    return c


def timed(fn):
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def bare_floor(jobs, settings, bare) -> float:
    """Seconds of bare stepping of all ``jobs``, one after the other."""
    return sum(floor(bare, job, settings) for job in jobs)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--workers', type=int, nargs='+', default=[1, 2])
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--flat-memory', type=int, default=0, metavar='N',
                        help='solutions of the 1,000-parametrization query (0: skip)')
    args = parser.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', str(130 + os.getpid() % 30))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

    import pybullet
    from pybullet_utils.bullet_client import BulletClient
    import rclpy

    from projection_server import prolog_bridge
    from projection_server.simulation.job import Job
    from projection_server.simulation.settings import load_settings

    prolog_bridge.load()
    settings = load_settings()
    grasping = scenario('grasping')
    jobs = [Job.checked(grasping, 'grasp_object', {'force': f, 'position': p})
            for p in POSITIONS for f in FORCES]
    first_job = Job.checked(grasping, 'grasp_object', FIRST_PARAMS)
    bare = BulletClient(connection_mode=pybullet.DIRECT)
    bare_floor(jobs[:2], settings, bare)   # warm-up
    rclpy.init()
    runs: dict[int, list[float]] = {}
    floors: list[float] = []
    parallel: dict[int, list[float]] = {}
    extra: dict[str, object] = {}
    grid = None
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for r in range(args.repeat):
                for workers in args.workers:
                    floors.append(bare_floor(jobs, settings, bare))
                    parallel.setdefault(workers, []).append(
                        parallel_floor(jobs, settings, workers))
                    bag_dir = tempfile.mkdtemp(dir=tmp)
                    last = r == args.repeat - 1 and workers == args.workers[-1]
                    with node(workers, bag_dir, Path(tmp) / f'node-{r}-{workers}.log') as proc:
                        proc.wait_for_service('/projection_server/query')
                        with client() as c:
                            c.once('true')   # the node is up and Prolog loaded
                            elapsed, grid = timed(lambda: c.all(QUERY, timeout=600.0))
                            runs.setdefault(workers, []).append(elapsed)
                            print(f'  workers={workers} run {r + 1}: {elapsed:.2f} s, '
                                  f'floor {floors[-1] / workers:.2f} s, bare in {workers} '
                                  f'processes {parallel[workers][-1]:.2f} s', flush=True)
                            if last:
                                extra = measure_last(c, proc.proc.pid, first_job,
                                                     settings, bare)
            if args.flat_memory:
                extra['flat'] = flat_memory(args.flat_memory, args.workers[-1], tmp)
    finally:
        bare.disconnect()
        rclpy.try_shutdown()
    report(args, settings, runs, floors, parallel, extra, grid)
    return 0


def measure_last(c, pid: int, first_job, settings, bare) -> dict[str, object]:
    out: dict[str, object] = {'node_rss': rss_mb(pid), 'worker_rss': worker_rss(pid)}
    cached = [timed(lambda: c.all(QUERY, timeout=600.0))[0] for _ in range(5)]
    out['cached'] = statistics.median(cached)
    with c.query(FIRST, timeout=600.0) as solutions:
        start = time.perf_counter()
        next(iter(solutions))
        out['first'] = time.perf_counter() - start
    out['first_floor'] = statistics.median(floor(bare, first_job, settings) for _ in range(3))
    return out


def flat_memory(solutions: int, workers: int, tmp: str) -> list[tuple[int, float, float]]:
    """(solutions taken, node RSS, largest worker RSS) every solutions/5 solutions."""
    rows = []
    every = max(1, solutions // 5)
    with node(workers, tempfile.mkdtemp(dir=tmp), Path(tmp) / 'node-flat.log') as proc:
        proc.wait_for_service('/projection_server/query')
        with client() as c:
            c.once('true')
            rows.append((0, rss_mb(proc.proc.pid), 0.0))
            with c.query(MANY, timeout=600.0) as stream:
                for n, _ in enumerate(stream, start=1):
                    if n % every == 0:
                        rows.append((n, rss_mb(proc.proc.pid), max(worker_rss(proc.proc.pid),
                                                               default=0.0)))
                        print(f'  flat memory: {n} solutions, node {rows[-1][1]:.0f} MB, '
                              f'worker {rows[-1][2]:.0f} MB', flush=True)
                    if n >= solutions:
                        break
    return rows


def report(args, settings, runs, floors, parallel, extra, grid) -> None:
    per_run_floor = statistics.median(floors)
    print('projection throughput benchmark (Table I grasping query through the service)')
    print(f'  settings: {PROJECTIONS} projections, ALL_SOLUTIONS, repeat={args.repeat} per '
          f'worker count, a fresh node and empty bag_dir each run; physics from '
          f'config/physics.yaml ({settings.physics.rate_hz} Hz, '
          f'{settings.physics.solver_iterations} solver iterations); python '
          f'{platform.python_version()}, {os.cpu_count()} cores, load average '
          f'{os.getloadavg()[0]:.1f}')
    print(f'  bare stepping of the 18 grasps: median {per_run_floor:.2f} s '
          f'(runs {", ".join(f"{f:.2f}" for f in floors)})')
    base = statistics.median(runs[args.workers[0]])
    for workers, times in runs.items():
        med = statistics.median(times)
        bound = per_run_floor / workers
        measured = statistics.median(parallel[workers])
        print(f'  workers={workers}: median {med:6.2f} s ({med / PROJECTIONS * 1e3:5.0f} ms per '
              f'projection), floor {bound:5.2f} s, ratio {med / bound:4.2f}x, speed-up '
              f'{base / med:4.2f}x; bare in {workers} processes {measured:.2f} s, ratio '
              f'{med / measured:4.2f}x')
    if extra:
        print(f'  cached re-query: median {extra["cached"] * 1e3:.0f} ms (5 runs)')
        print(f'  first INCREMENTAL solution (a new grasp): {extra["first"]:.2f} s, its bare '
              f'stepping {extra["first_floor"]:.2f} s, ratio '
              f'{extra["first"] / extra["first_floor"]:.2f}x')
        workers_rss = ', '.join(f'{m:.0f}' for m in extra['worker_rss'])
        print(f'  memory after Table I: node {extra["node_rss"]:.0f} MB, workers '
              f'{workers_rss} MB')
    for n, node_mb, worker_mb in extra.get('flat', []):
        print(f'  1,000-parametrization INCREMENTAL query, {n:4d} solutions: node '
              f'{node_mb:.0f} MB, worker {worker_mb:.0f} MB')
    if grid:
        rows: dict[float, list[str]] = {}
        for s in grid:
            rows.setdefault(s['P'], []).append(str(s['O']))
        for p, outcomes in rows.items():
            print(f'  position {p:+.2f}: ' + ' '.join(f'{o:5s}' for o in outcomes))


if __name__ == '__main__':
    sys.exit(main())
