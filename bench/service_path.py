"""What the service path adds between its workers and Prolog: Table I in one process, no ROS.

Loads the server's Prolog, starts the local worker pool with ``--workers`` warm workers and
runs the Table I query (18 grasps, a fresh bag directory each run) through Prolog as the
query service does, while recording, for every projection, how long its worker was busy
with it (from sending the job to receiving the timeline, pickling included). The workers'
busy time divided by their number is the floor of the service path; the query's wall time
over it is what Prolog, the pool, the bag store and the hand-over cost on top, and what
idle workers between jobs cost. Also printed: the CPU time of this process (everything but
the workers) and the longest a worker waited between two jobs of the query, and the same
query asked again ten times with every bag made (a cached re-query: Prolog and the keys).

    tools/with_env.sh python bench/service_path.py --workers 1 2 --repeat 3
"""

from __future__ import annotations

import logging
import os
import resource
import statistics
import sys
import tempfile
import threading
import time

import harness


def cpu_self() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


class Recorder(logging.Handler):
    """(worker thread, sent, answered) of every projection, from the local pool's debug log
    of when it gives a worker a projection and when the worker answers."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.spans: list[tuple[str, float, float]] = []
        self._sent: dict[str, float] = {}
        self._lock = threading.Lock()
        log = logging.getLogger('projection_server.workers.local.pool')
        log.setLevel(logging.DEBUG)
        log.addHandler(self)

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        bag = message.rsplit(': ', 1)[-1]
        with self._lock:
            if message.startswith('projection sent'):
                self._sent[bag] = record.created
            elif message.startswith('projection answered') and bag in self._sent:
                self.spans.append((record.threadName, self._sent.pop(bag), record.created))

    def take(self) -> list[tuple[str, float, float]]:
        with self._lock:
            spans, self.spans = self.spans, []
        return spans


def run(workers: int, recorder: Recorder) -> dict[str, float]:
    from projection_server import projection
    from projection_server.service import prolog_bridge

    with tempfile.TemporaryDirectory() as bags:
        projection.configure(bag_dir=bags, workers=workers)   # starts the workers
        harness.wait_warm(os.getpid(), workers)   # and warm, as a node's workers soon are
        recorder.take()
        cpu, start = cpu_self(), time.perf_counter()
        with prolog_bridge.solutions(harness.TABLE_I,
                                     {'timeout': 600.0, 'sandbox': True}) as results:
            solutions = [r for r in results if r['status'] == 'solution']
        wall, cpu = time.perf_counter() - start, cpu_self() - cpu
        spans = recorder.take()
        cached = []
        for _ in range(10):
            again = time.perf_counter()
            with prolog_bridge.solutions(harness.TABLE_I,
                                         {'timeout': 60.0, 'sandbox': True}) as results:
                if sum(r['status'] == 'solution' for r in results) != 18:
                    raise RuntimeError('the cached query lost solutions')
            cached.append(time.perf_counter() - again)
        projection.shutdown()
    if len(solutions) != 18:
        raise RuntimeError(f'{len(solutions)} solutions instead of 18')
    busy = sum(end - begin for _, begin, end in spans)
    gaps = []
    for slot in {name for name, _, _ in spans}:
        own = sorted((b, e) for name, b, e in spans if name == slot)
        gaps += [b2 - e1 for (_, e1), (b2, _) in zip(own, own[1:])]
    return {'wall': wall, 'floor': busy / workers, 'cpu': cpu,
            'gap': max(gaps, default=0.0), 'cached': statistics.median(cached)}


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3)
    parser.add_argument('--workers', type=int, nargs='+', default=[1, 2])
    args = parser.parse_args()

    from projection_server.service import prolog_bridge

    harness.prolog()   # the server's Prolog, loaded
    prolog_bridge.attach_engine()
    recorder = Recorder()
    runs: dict[int, list[dict[str, float]]] = {}
    for r in range(args.repeat):
        for workers in args.workers:
            result = run(workers, recorder)
            runs.setdefault(workers, []).append(result)
            print(f'  workers={workers} run {r + 1}: {result["wall"]:.2f} s, busy / workers '
                  f'{result["floor"]:.2f} s, this process {result["cpu"]:.2f} s CPU, '
                  f'longest idle between jobs {result["gap"] * 1e3:.1f} ms, cached re-query '
                  f'{result["cached"] * 1e3:.1f} ms', flush=True)
    print('service path benchmark (Table I through Prolog and the pool, in one process)')
    print(f'  settings: 18 projections, a fresh bag directory and warm workers each run, '
          f'repeat={args.repeat}; {harness.machine()}')
    for workers, results in runs.items():
        ratio = statistics.median(x['wall'] / x['floor'] for x in results)
        print(f'  workers={workers}: median {statistics.median(x["wall"] for x in results):.2f}'
              f' s against the workers\' busy time / {workers} '
              f'{statistics.median(x["floor"] for x in results):.2f} s: ratio {ratio:.3f}x; '
              f'this process {statistics.median(x["cpu"] for x in results):.2f} s CPU; '
              f'longest idle between jobs {max(x["gap"] for x in results) * 1e3:.1f} ms; '
              f'cached re-query {statistics.median(x["cached"] for x in results) * 1e3:.1f} '
              'ms')
    return 0


if __name__ == '__main__':
    sys.exit(main())
