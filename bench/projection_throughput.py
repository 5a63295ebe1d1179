"""Table I through the service against the bare physics of its 18 grasps, measured in the same run.

For each number of simulation workers, starts a projection_server with an empty bag
directory (no cached projections) and sends the paper's grasping query (6 forces x 3
positions) once in ALL_SOLUTIONS mode; repeats. In the same run, this process steps the
same 18 grasps bare (world, program, ``stepSimulation`` and the egg's contact query per
step; :func:`harness.floor`, as in ``bench/pipeline_overhead.py``): the floor of W workers
is that sum divided by W.
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

from pathlib import Path
import statistics
import sys
import tempfile
import time

import harness

POSITIONS = [-0.02, 0.00, 0.02]
FORCES = [1, 3, 5, 7, 9, 11]
PROJECTIONS = len(POSITIONS) * len(FORCES)
# Grasps that Table I does not make: each first solution needs a new projection (one query
# per position; the first force is asked for, the others are prefetched).
FIRST = ('make_projection(grasping, grasp_object, [(F, force, [4, 6, 8]), '
         '(P, position, [{}])], TL), ( occurs(break, _, TL) -> O = break ; O = ok )')
FIRST_POSITIONS = [0.01, -0.01, 0.015]

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
    """Wall and CPU seconds of one projection's pipeline in this process (its timeline
    made from the records, as a worker makes it)."""
    from projection_server.workers.run import project

    with tempfile.TemporaryDirectory() as tmp:
        start, cpu = time.perf_counter(), time.process_time()
        project(_simulator, job, settings, Path(tmp) / 'bag')
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


def timed(fn):
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def bare_floor(jobs, settings, bare) -> float:
    """Seconds of bare stepping of all ``jobs``, one after the other."""
    return sum(harness.floor(bare, job, settings)[0] for job in jobs)


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3)
    parser.add_argument('--workers', type=int, nargs='+', default=[1, 2])
    args = parser.parse_args()
    harness.ros_domain(130)

    import rclpy

    from projection_server.settings import load_settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Simulator

    settings = load_settings()
    grasping = harness.kb_scenario('grasping')
    jobs = [Job.checked(grasping, 'grasp_object', {'force': f, 'position': p})
            for p in POSITIONS for f in FORCES]
    first_jobs = [Job.checked(grasping, 'grasp_object', {'force': 4, 'position': p})
                  for p in FIRST_POSITIONS]
    simulator = Simulator()   # a client of its own for the floor, as pipeline_overhead.py's
    bare = simulator.client
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
                        harness.parallel_floor(jobs, settings, workers))
                    piped, piped_cpu = parallel_pipeline(jobs, settings, workers)
                    pipelines.setdefault(workers, []).append(piped)
                    bag_dir = tempfile.mkdtemp(dir=tmp)
                    last = r == args.repeat - 1 and workers == args.workers[-1]
                    params = {'projection_workers': workers, 'bag_dir': bag_dir,
                              'default_timeout': 600.0, 'max_solutions': 2000}
                    with harness.start_node(params, Path(tmp) / f'node-{r}-{workers}.log'
                                            ) as proc, harness.client() as c:
                        pid = proc.proc.pid
                        pids = harness.worker_pids(pid)
                        cpu = harness.cpu_seconds(pid)
                        cpu_workers = sum(harness.cpu_seconds(p) for p in pids)
                        elapsed, grid = timed(lambda: c.all(harness.TABLE_I, timeout=600.0))
                        runs.setdefault(workers, []).append(elapsed)
                        node_cpu.setdefault(workers, []).append(harness.cpu_seconds(pid) - cpu)
                        cpu_workers = sum(harness.cpu_seconds(p) for p in pids) - cpu_workers
                        cpu_ratio.setdefault(workers, []).append(
                            (node_cpu[workers][-1] + cpu_workers) / piped_cpu)
                        print(f'  workers={workers} run {r + 1}: {elapsed:.2f} s, '
                              f'floor {floors[-1] / workers:.2f} s, bare in {workers} '
                              f'processes {parallel[workers][-1]:.2f} s, pipeline in '
                              f'{workers} processes {pipelines[workers][-1]:.2f} s, node '
                              f'CPU {node_cpu[workers][-1]:.2f} s', flush=True)
                        if last:
                            extra = measure_last(c, pid, first_jobs, settings, bare)
    finally:
        simulator.close()
        rclpy.try_shutdown()
    report(args, settings, runs, floors, parallel, pipelines, node_cpu, cpu_ratio, extra,
           grid)
    return 0


def measure_last(c, pid: int, first_jobs, settings, bare) -> dict[str, object]:
    out: dict[str, object] = {'node_rss': harness.rss_mb(pid), 'worker_rss': [
        harness.rss_mb(worker) for worker in harness.worker_pids(pid)]}
    cached = [timed(lambda: c.all(harness.TABLE_I, timeout=600.0))[0] for _ in range(5)]
    out['cached'] = statistics.median(cached)
    firsts = []
    for position in FIRST_POSITIONS:
        with c.query(FIRST.format(position), timeout=600.0) as solutions:
            start = time.perf_counter()
            next(iter(solutions))
            firsts.append(time.perf_counter() - start)
        # the closed query's prefetched ones finish
        harness.wait_warm(pid, len(harness.worker_pids(pid)))
    out['first'] = statistics.median(firsts)
    out['first_floor'] = statistics.median(harness.floor(bare, job, settings)[0]
                                           for job in first_jobs)
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
          f'{settings.physics.solver_iterations} solver iterations); {harness.machine()}')
    print(f'  bare stepping of the 18 grasps: median {per_run_floor:.2f} s '
          f'(runs {harness.listed(floors)})')
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
