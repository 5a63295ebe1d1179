"""Table I through the service against the bare physics of its 18 grasps, measured in the same run.

For each number of simulation workers, starts a projection_server with an empty bag
directory (no cached projections) and sends the paper's grasping query (6 forces x 3
positions) once in ALL_SOLUTIONS mode; repeats. In the same run, this process steps the
same 18 grasps bare (world, program, ``stepSimulation`` and the egg's contact query per
step; see ``bench/pipeline_overhead.py``): the floor of W workers is that sum divided by W.
It also steps them bare in W processes at once: on a machine shared with other work, that
wall time is the floor W workers can reach there and then. And it runs the 18 projections'
full pipeline (a warm simulator: world, program, object models, monitor, bag, timeline;
what a worker does) in W processes at once, without node, Prolog or pool: the service's
own cost is its wall time over that one. The node's CPU time during the query is its share
of the cores.
On the last node it also measures:

* the first solution of an INCREMENTAL query over grasps not made yet, against the bare
  stepping and the pipeline (in this process, warm) of that one grasp;
* the cached re-query (the same Table I query again: every bag and timeline exists);
* the resident memory of the node and of each worker after Table I.

A 1,000-parametrization INCREMENTAL query in flat memory: ``bench/flat_memory.py``.

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
# Grasps that Table I does not make: each first solution needs a new projection (one query
# per position; the first force is asked for, the others are prefetched).
FIRST = ('make_projection(grasping, grasp_object, [(F, force, [4, 6, 8]), '
         '(P, position, [{}])], TL), ( occurs(break, _, TL) -> O = break ; O = ok )')
FIRST_POSITIONS = [0.01, -0.01, 0.015]


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


def workers_of(pid: int) -> list[int]:
    """The node's projection worker processes: the children of its forkserver."""
    out = []
    for child in children(pid):
        try:
            cmdline = Path(f'/proc/{child}/cmdline').read_bytes()
        except OSError:
            continue
        if b'forkserver' in cmdline:
            out += children(child)
    return out


def worker_rss(pid: int) -> list[float]:
    """RSS of the node's projection workers [MB]."""
    return [rss_mb(worker) for worker in workers_of(pid)]


def cpu_seconds(pid: int) -> float:
    """User and system CPU time of a process, all its threads [s] (0 if it is gone)."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


_simulator = None


def _pipeline_start() -> None:
    """A pipeline process: a warm simulator, as a worker has it (warm-up included)."""
    global _simulator
    from projection_server.simulation.runner import Simulator
    from projection_server.settings import load_settings
    from projection_server.workers.warm_up import warm_up

    _simulator = Simulator()
    warm_up(_simulator, load_settings())


def _pipeline_run(job, settings) -> tuple[float, float]:
    """Wall and CPU seconds of one projection's pipeline in this process."""
    with tempfile.TemporaryDirectory() as tmp:
        start, cpu = time.perf_counter(), time.process_time()
        _simulator.run(job, settings, Path(tmp) / 'bag')
        return time.perf_counter() - start, time.process_time() - cpu


def parallel_pipeline(jobs, settings, workers: int) -> tuple[float, float]:
    """Wall time [s] of the full pipeline of ``jobs`` in ``workers`` warm processes at once,
    and their CPU time [s]: what the workers themselves need, without node, Prolog, pool or
    bag directory."""
    from concurrent.futures import ProcessPoolExecutor
    import multiprocessing

    with ProcessPoolExecutor(workers, multiprocessing.get_context('forkserver'),
                             initializer=_pipeline_start) as pool:
        list(pool.map(_pipeline_run, jobs[:workers], [settings] * workers))   # all started
        start = time.perf_counter()
        times = list(pool.map(_pipeline_run, jobs, [settings] * len(jobs)))
        return time.perf_counter() - start, sum(cpu for _, cpu in times)


def node(workers: int, bag_dir: str, log: Path, **params: object):
    from projection_server.client.launcher import node_command, NodeProcess

    return NodeProcess(node_command('/projection_server', {
        'projection_workers': workers, 'bag_dir': bag_dir, 'default_timeout': 600.0,
        'max_solutions': 2000, **params}), log)


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
    return sum(floor(bare, job, settings)[0] for job in jobs)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--workers', type=int, nargs='+', default=[1, 2])
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args()
    os.environ.setdefault('ROS_DOMAIN_ID', str(130 + os.getpid() % 30))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

    import pybullet
    import rclpy

    from projection_server.service import prolog_bridge
    from projection_server.simulation.job import Job
    from projection_server.simulation.physics import bound_client
    from projection_server.settings import load_settings

    prolog_bridge.load()
    settings = load_settings()
    grasping = scenario('grasping')
    jobs = [Job.checked(grasping, 'grasp_object', {'force': f, 'position': p})
            for p in POSITIONS for f in FORCES]
    first_jobs = [Job.checked(grasping, 'grasp_object', {'force': 4, 'position': p})
                  for p in FIRST_POSITIONS]
    bare = bound_client(pybullet.DIRECT)   # as the workers' and pipeline_overhead.py's
    bare_floor(jobs[:2], settings, bare)   # warm-up
    rclpy.init()
    runs: dict[int, list[float]] = {}
    floors: list[float] = []
    parallel: dict[int, list[float]] = {}
    pipelines: dict[int, list[float]] = {}
    node_cpu: dict[int, list[float]] = {}
    # CPU seconds of the service (node and workers) over those of the pipeline alone: what
    # the service adds in work, which a loaded machine does not inflate as it does wall time
    cpu_ratio: dict[int, list[float]] = {}
    extra: dict[str, object] = {}
    grid = None
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for r in range(args.repeat):
                for workers in args.workers:
                    floors.append(bare_floor(jobs, settings, bare))
                    parallel.setdefault(workers, []).append(
                        parallel_floor(jobs, settings, workers))
                    piped, piped_cpu = parallel_pipeline(jobs, settings, workers)
                    pipelines.setdefault(workers, []).append(piped)
                    bag_dir = tempfile.mkdtemp(dir=tmp)
                    last = r == args.repeat - 1 and workers == args.workers[-1]
                    with node(workers, bag_dir, Path(tmp) / f'node-{r}-{workers}.log') as proc:
                        proc.wait_for_service('/projection_server/query')
                        with client() as c:
                            c.once('true')   # the node is up and Prolog loaded
                            wait_warm(proc.proc.pid, workers)
                            pids = workers_of(proc.proc.pid)
                            cpu = cpu_seconds(proc.proc.pid)
                            cpu_workers = sum(cpu_seconds(p) for p in pids)
                            elapsed, grid = timed(lambda: c.all(QUERY, timeout=600.0))
                            runs.setdefault(workers, []).append(elapsed)
                            node_cpu.setdefault(workers, []).append(
                                cpu_seconds(proc.proc.pid) - cpu)
                            cpu_workers = sum(cpu_seconds(p) for p in pids) - cpu_workers
                            cpu_ratio.setdefault(workers, []).append(
                                (node_cpu[workers][-1] + cpu_workers) / piped_cpu)
                            print(f'  workers={workers} run {r + 1}: {elapsed:.2f} s, '
                                  f'floor {floors[-1] / workers:.2f} s, bare in {workers} '
                                  f'processes {parallel[workers][-1]:.2f} s, pipeline in '
                                  f'{workers} processes {pipelines[workers][-1]:.2f} s, node '
                                  f'CPU {node_cpu[workers][-1]:.2f} s', flush=True)
                            if last:
                                extra = measure_last(c, proc.proc.pid, first_jobs,
                                                     settings, bare)
    finally:
        bare.disconnect()
        rclpy.try_shutdown()
    report(args, settings, runs, floors, parallel, pipelines, node_cpu, cpu_ratio, extra,
           grid)
    return 0


def wait_warm(pid: int, workers: int, timeout: float = 120.0) -> None:
    """Until the node's workers have started and warmed up (each then waits for a job,
    using no CPU): what a node that has been up for a while offers its first query."""
    deadline = time.monotonic() + timeout
    last: dict[int, float] = {}
    while time.monotonic() < deadline:
        pids = workers_of(pid)
        now = {p: cpu_seconds(p) for p in pids}
        if len(pids) == workers and now == last:
            return
        last = now
        time.sleep(0.25)
    raise RuntimeError(f'the workers of node {pid} did not settle within {timeout:g} s')


def measure_last(c, pid: int, first_jobs, settings, bare) -> dict[str, object]:
    out: dict[str, object] = {'node_rss': rss_mb(pid), 'worker_rss': worker_rss(pid)}
    cached = [timed(lambda: c.all(QUERY, timeout=600.0))[0] for _ in range(5)]
    out['cached'] = statistics.median(cached)
    firsts = []
    for position in FIRST_POSITIONS:
        with c.query(FIRST.format(position), timeout=600.0) as solutions:
            start = time.perf_counter()
            next(iter(solutions))
            firsts.append(time.perf_counter() - start)
        wait_warm(pid, len(workers_of(pid)))   # the closed query's prefetched ones finish
    out['first'] = statistics.median(firsts)
    out['first_floor'] = statistics.median(floor(bare, job, settings)[0] for job in first_jobs)
    _pipeline_start()
    out['first_pipeline'] = statistics.median(_pipeline_run(job, settings)[0]
                                              for job in first_jobs)
    return out


def report(args, settings, runs, floors, parallel, pipelines, node_cpu, cpu_ratio, extra,
           grid) -> None:
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
    first = args.workers[0]
    base = statistics.median(runs[first])
    for workers, times in runs.items():
        med = statistics.median(times)
        bound = per_run_floor / workers
        measured = statistics.median(parallel[workers])
        piped = statistics.median(pipelines[workers])
        # The service's cost over its workers' pipeline, run by run (same load).
        over = statistics.median(t / p for t, p in zip(times, pipelines[workers]))
        cpu = statistics.median(node_cpu[workers])
        print(f'  workers={workers}: median {med:6.2f} s ({med / PROJECTIONS * 1e3:5.0f} ms per '
              f'projection), floor {bound:5.2f} s, ratio {med / bound:4.2f}x, speed-up '
              f'{base / med:4.2f}x; bare in {workers} processes {measured:.2f} s, ratio '
              f'{med / measured:4.2f}x')
        print(f'             pipeline in {workers} processes {piped:.2f} s (speed-up '
              f'{statistics.median(pipelines[first]) / piped:4.2f}x, bare '
              f'{statistics.median(parallel[first]) / measured:4.2f}x): the service over its '
              f"workers' pipeline {over:4.2f}x; node CPU {cpu:.2f} s; CPU time of node "
              f'and workers over the pipeline\'s {statistics.median(cpu_ratio[workers]):4.2f}x')
    if extra:
        print(f'  cached re-query: median {extra["cached"] * 1e3:.0f} ms (5 runs)')
        print(f'  first INCREMENTAL solution of a new grasp (median of {len(FIRST_POSITIONS)}): '
              f'{extra["first"]:.2f} s, its bare stepping {extra["first_floor"]:.2f} s, ratio '
              f'{extra["first"] / extra["first_floor"]:.2f}x; its pipeline '
              f'{extra["first_pipeline"]:.2f} s, ratio '
              f'{extra["first"] / extra["first_pipeline"]:.2f}x')
        workers_rss = ', '.join(f'{m:.0f}' for m in extra['worker_rss'])
        print(f'  memory after Table I: node {extra["node_rss"]:.0f} MB, workers '
              f'{workers_rss} MB')
    if grid:
        rows: dict[float, list[str]] = {}
        for s in grid:
            rows.setdefault(s['P'], []).append(str(s['O']))
        for p, outcomes in rows.items():
            print(f'  position {p:+.2f}: ' + ' '.join(f'{o:5s}' for o in outcomes))


if __name__ == '__main__':
    sys.exit(main())
