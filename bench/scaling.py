"""Projections on the local and the ray backend, with 1 and 2 workers: the per-projection
overhead of Ray against local worker processes, and the speed-up from a second worker.

Two batches: the paper's Table I (18 egg grasps: 6 forces x 3 positions) and a batch of
pours (Table II's 9 pours at the centre: 3 angles x 3 holding times, one family that both
backends run as a tree). The scenarios are the knowledge base's (``grasping`` and
``pouring``, from the server's Prolog in this process). Each backend gets a fresh bag
directory (nothing cached) and warm workers (one warm-up projection per worker, not
timed); a batch is submitted at once (``submit_all``, as a query's prefetch
queues it) and timed until its last projection is published. Local and ray runs alternate,
so a loaded machine slows both alike; the local backend is the floor Ray is measured
against.

    tools/with_env.sh python bench/scaling.py --repeat 3
    tools/with_env.sh python bench/scaling.py --ray-address auto   # an existing cluster
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time

from projection_server.reproduce import paper

import harness

POUR_ANGLES = paper.POUR_ANGLES
POUR_TIMES = paper.POUR_TIMES
BATCHES = ('table1', 'pours')


def batches(scenarios: dict[str, dict]) -> dict[str, list]:
    from projection_server.simulation import Job

    grasp = [Job.checked(scenarios['grasping'], 'grasp_object',
                         {'force': float(f), 'position': float(p)})
             for p in paper.GRASP_POSITIONS for f in paper.GRASP_FORCES]
    pours = [Job.checked(scenarios['pouring'], 'pour', {'angle': float(a), 'time': float(t)})
             for t in POUR_TIMES for a in POUR_ANGLES]
    return {'table1': grasp, 'pours': pours}


def warm_up(backend, scenarios: dict[str, dict]) -> None:
    """One untimed projection per worker, at once: every worker started and warm."""
    from projection_server.simulation import Job

    jobs = [Job.checked(scenarios['grasping'], 'grasp_object',
                        {'force': 2.0 + 0.25 * i, 'position': 0.01})
            for i in range(backend.workers)]
    for future in [backend.submit(job, 600.0) for job in jobs]:
        future.result(600.0)


def timed(backend, jobs: list) -> float:
    start = time.perf_counter()
    futures = backend.submit_all(jobs, 600.0)
    for future in futures:
        future.result(1200.0)
    return time.perf_counter() - start


def run_once(kind: str, workers: int, address: str, scenarios, jobs) -> dict[str, float]:
    from projection_server.workers import create_backend

    options = {'address': address} if kind == 'ray' else {}
    with tempfile.TemporaryDirectory() as bag_dir:
        backend = create_backend(kind, bag_dir, workers, **options)
        try:
            warm_up(backend, scenarios)
            return {name: timed(backend, jobs[name]) for name in BATCHES}
        finally:
            backend.close()


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3)
    parser.add_argument('--workers', type=int, nargs='+', default=[1, 2])
    parser.add_argument('--ray-address', default='',
                        help='join this Ray cluster (auto, host:port); default: start a '
                             'one-node cluster on this machine for the run')
    args = parser.parse_args()

    from projection_server.simulation import ProjectionError
    from projection_server.workers.ray.local_cluster import LocalCluster

    scenarios = {name: harness.kb_scenario(name) for name in ('grasping', 'pouring')}
    jobs = batches(scenarios)
    cluster = None
    address = args.ray_address
    if not address:
        cluster = LocalCluster(nodes=1, cpus_per_node=max(args.workers)).__enter__()
        address = cluster.address
        os.environ.update(cluster.env)
    times: dict[tuple[str, int, str], list[float]] = {}
    try:
        for r in range(args.repeat):
            for workers in args.workers:
                for kind in ('local', 'ray'):
                    try:
                        result = run_once(kind, workers, address, scenarios, jobs)
                    except ProjectionError as exc:   # reported, and left out of the medians
                        print(f'run {r + 1}/{args.repeat} {kind:5} workers={workers}: '
                              f'failed: {exc}', flush=True)
                        continue
                    for name, seconds in result.items():
                        times.setdefault((kind, workers, name), []).append(seconds)
                    print(f'run {r + 1}/{args.repeat} {kind:5} workers={workers}: '
                          + ', '.join(f'{n} {s:.2f} s' for n, s in result.items()),
                          flush=True)
    finally:
        if cluster is not None:
            cluster.stop()

    print(f'\nmachine: {harness.machine()}; '
          f'ray at {args.ray_address or "a one-node cluster started for the run"}')
    print(f'settings: {args.repeat} runs, fresh bag directory and warm workers per run; '
          f'Table I = {len(jobs["table1"])} grasps, pours = {len(jobs["pours"])} pours '
          f'(angles {", ".join(str(a) for a in POUR_ANGLES)} x holds '
          f'{", ".join(str(t) for t in POUR_TIMES)} s, centred)\n')
    print('| batch | workers | local median | ray median | ray overhead per projection '
          '| ray / local | speed-up local | speed-up ray |')
    print('|---|---|---|---|---|---|---|---|')
    for name in BATCHES:
        n = len(jobs[name])
        for workers in args.workers:
            if not all(times.get((k, w, name)) for k in ('local', 'ray')
                       for w in (workers, args.workers[0])):
                print(f'| {name} | {workers} | no complete runs |')
                continue
            local = statistics.median(times[('local', workers, name)])
            ray = statistics.median(times[('ray', workers, name)])
            base = args.workers[0]
            up_local = statistics.median(times[('local', base, name)]) / local
            up_ray = statistics.median(times[('ray', base, name)]) / ray
            print(f'| {name} | {workers} | {local:.2f} s | {ray:.2f} s '
                  f'| {1000 * (ray - local) * workers / n:+.0f} ms | {ray / local:.2f} '
                  f'| {up_local:.2f}x | {up_ray:.2f}x |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
