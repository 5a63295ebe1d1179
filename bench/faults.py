"""Faults against a live node: crash requests, workers killed mid-projection, a full disk.

Starts the projection_server node in its own process (private ROS domain on loopback) with
its bag directory on a small tmpfs (a size-limited directory; without permission to mount
one, a quota emulated by ``max_bags``), then

  1. sends the requests that used to crash the node or break it for good;
  2. kills a simulation worker (SIGKILL) at a random moment of running projections;
  3. runs new projections until the bag directory's disk is full;

and after each fault checks that the node still answers, that no partial bag is kept and
that the engines are free. Prints what survived.

    tools/with_env.sh python bench/faults.py [--kills 4] [--disk-mb 3] [--seed 1]
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import tempfile
import time

import harness

CRASH_REQUESTS = [
    ('timeout 1e10', dict(query='X = 1', timeout=1e10)),
    ('timeout inf', dict(query='X = 1', timeout=float('inf'))),
    ('text nested 30,000 deep', dict(query='X = ' + 'f(' * 30000 + 'a' + ')' * 30000)),
    ('write a 100,000-deep term', dict(query=(
        "length(Fs, 100000), maplist(=('f('), Fs), atomic_list_concat(Fs, O), "
        "format(atom(C), '~*c', [100000, 0')]), atomic_list_concat([O, a, C], Text), "
        "term_to_atom(T, Text), \\+ \\+ term_to_atom(T, _), X = done"), timeout=30.0)),
    ('parse 4,000,000 parentheses built by the query', dict(
        query="format(atom(O), '~*c', [4000000, 0'(]), term_to_atom(_, O)", timeout=30.0)),
    ('abandoned sleep(5) with timeout 1', dict(query='sleep(5)', timeout=1.0)),
    ('sleep(25) with timeout 1', dict(query='sleep(25)', timeout=1.0)),
    ('abort', dict(query='abort')),
    ('max_solutions 2^32-1 of repeat', dict(query='repeat', max_solutions=2 ** 32 - 1,
                                            mode='all')),
    ('trailing garbage', dict(query='X = 1. garbage ((((')),
    ('assertz(exception(undefined_predicate, _, fail))',
     dict(query='assertz(exception(undefined_predicate, _, fail))')),
    ('assertz(portray(_))', dict(query='assertz(portray(_))')),
    ('assertz(term_expansion(_, [])) + use_module',
     dict(query='assertz(term_expansion(_, [])), use_module(library(ugraphs))')),
    ('400M-character atom', dict(query="format(atom(A), '~*c', [400000000, 0'a]), "
                                       'atom_length(A, N)', timeout=30.0)),
]


class Client:
    def __init__(self, server: str):
        import rclpy
        from projection_interfaces.srv import PrologQuery
        from std_srvs.srv import Trigger
        self.rclpy = rclpy
        self.Q = PrologQuery.Request
        self.node = rclpy.create_node(f'faults_client_{os.getpid()}')
        self.query_client = self.node.create_client(PrologQuery, f'{server}/query')
        self.ping_client = self.node.create_client(Trigger, f'{server}/ping')
        self.Trigger = Trigger
        assert self.query_client.wait_for_service(timeout_sec=60)

    def send(self, query: str, mode: str = 'once', timeout: float = 0.0,
             max_solutions: int = 0):
        q = self.Q
        request = q(mode=q.ALL_SOLUTIONS if mode == 'all' else q.ONCE, query=query,
                    timeout=float(timeout), max_solutions=max_solutions)
        return self.query_client.call_async(request)

    def wait(self, future, limit: float = 300.0):
        self.rclpy.spin_until_future_complete(self.node, future, timeout_sec=limit)
        return future.result() if future.done() else None

    def ask(self, query: str, **kw):
        return self.wait(self.send(query, **kw))

    def stats(self) -> dict | None:
        future = self.ping_client.call_async(self.Trigger.Request())
        result = self.wait(future, 10.0)
        return json.loads(result.message) if result is not None else None

    def alive(self) -> bool:
        r = self.wait(self.send('X = 1'), 15.0)
        return r is not None and r.solutions == ['{"X":1}']

    def engines_free(self, within: float = 3.0) -> float | None:
        start = time.monotonic()
        while time.monotonic() - start < within:
            s = self.stats()
            if s is not None and s['engines'] == 0:
                return time.monotonic() - start
            time.sleep(0.05)
        return None


def bag_health(bag_dir: Path) -> tuple[int, int]:
    """(complete bags, partial or temporary entries) in the bag directory."""
    complete = partial = 0
    for entry in bag_dir.iterdir():
        if entry.name.startswith('.tmp-') or not (entry / 'metadata.yaml').is_file():
            partial += 1
        else:
            complete += 1
    return complete, partial


def projection_query(forces: list[float]) -> str:
    values = ', '.join(f'{f:.4f}' for f in forces)
    return (f'make_projection(grasping, grasp_object, [(F, force, [{values}])], TL), '
            '( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip ; O = ok )')


def main() -> int:
    parser = harness.arguments(__doc__, seed=1)
    parser.add_argument('--kills', type=int, default=4, help='workers killed mid-projection')
    parser.add_argument('--disk-mb', type=int, default=8, help='size of the bag tmpfs')
    args = parser.parse_args()
    rng = random.Random(args.seed)

    harness.ros_domain(10, 90)
    import rclpy

    work = Path(tempfile.mkdtemp(prefix='faults-'))
    bag_dir = work / 'bags'
    bag_dir.mkdir()
    mounted = subprocess.run(['mount', '-t', 'tmpfs', '-o', f'size={args.disk_mb}m', 'tmpfs',
                              str(bag_dir)], capture_output=True).returncode == 0
    params = {'bag_dir': str(bag_dir), 'default_timeout': 20.0, 'max_engines': 4,
              'projection_workers': 1}
    if not mounted:
        params['max_bags'] = 3
    print(f'bag_dir {bag_dir}: ' + (f'tmpfs of {args.disk_mb} MiB' if mounted
                                    else 'no tmpfs (not permitted): quota max_bags=3'))
    survived: list[tuple[str, str, bool]] = []
    rclpy.init()
    try:
        with harness.start_node(params, work / 'node.log', node='/faults_server') as proc:
            client = Client('/faults_server')
            pid = client.stats()['pid']

            print('\n1. requests that used to crash or break the node')
            for name, request in CRASH_REQUESTS:
                start = time.monotonic()
                r = client.ask(**request)
                took = time.monotonic() - start
                outcome = 'no answer' if r is None else (
                    'ok' if r.ok else r.error_kind or 'error')
                ok = proc.running and client.alive()
                freed = client.engines_free(within=120.0)
                survived.append((name, f'{outcome} in {took:.2f} s', ok))
                print(f'  {name:<52} {outcome:<16} {took:6.2f} s  node '
                      f'{"serving" if ok else "BROKEN"}; engines free '
                      + ('at once' if freed is not None and freed < 0.1 else
                         f'{freed:.1f} s later' if freed is not None else 'NEVER'))
            for check, text, kind in (
                    ('undefined predicates still raise', 'no_such_pred_q', 'existence_error'),
                    ('portray still unset', "format(atom(X), '~p', [f(x)])", ''),
                    ('a library still loads', 'use_module(library(ugraphs)), '
                     'vertices_edges_to_ugraph([a], [], X)', '')):
                r = client.ask(text)
                if kind:
                    ok = r is not None and r.error_kind == kind
                else:
                    ok = r is not None and r.ok and bool(r.solutions) and (
                        'portray' not in check or '"f(x)"' in r.solutions[0])
                survived.append((check, 'ok' if ok else 'poisoned', ok))
                print(f'  {check:<52} {"ok" if ok else "POISONED"}')

            print('\n2. workers killed (SIGKILL) mid-projection')
            for i in range(args.kills):
                forces = [3.0 + i + 0.01 * k for k in range(1, 4)]
                future = client.send(projection_query(forces), mode='all', timeout=120.0)
                deadline = time.monotonic() + rng.uniform(0.5, 4.0)
                victims: list[int] = []
                while time.monotonic() < deadline:
                    rclpy.spin_once(client.node, timeout_sec=0.05)
                    victims = harness.worker_pids(pid)
                killed = rng.choice(victims) if victims and not future.done() else None
                if killed is not None:
                    os.kill(killed, signal.SIGKILL)
                r = client.wait(future)
                outcome = 'no answer' if r is None else (
                    f'ok ({len(r.solutions)} solutions)' if r.ok else r.error_kind)
                message = '' if r is None or r.ok else r.message[:60]
                complete, partial = bag_health(bag_dir)
                ok = (proc.running and client.alive() and partial == 0
                      and client.engines_free(within=10.0) is not None)
                again = client.ask(projection_query(forces), mode='all', timeout=120.0)
                recovered = again is not None and again.ok
                survived.append((f'kill {i + 1}', outcome, ok and recovered))
                print(f'  kill {i + 1}: pid {killed}: {outcome} {message!r}; bags complete '
                      f'{complete}, partial {partial}; rerun '
                      f'{"ok" if recovered else "FAILED"}; node '
                      f'{"serving" if ok else "BROKEN"}')

            print('\n3. projections until the bag directory is full')
            kinds: dict[str, int] = {}
            failures = 0
            for i in range(60):
                r = client.ask(projection_query([6.0 + 0.1 * i]), mode='all', timeout=120.0)
                kind = 'no answer' if r is None else ('ok' if r.ok else r.error_kind)
                kinds[kind] = kinds.get(kind, 0) + 1
                if r is not None and not r.ok:
                    print(f'  projection {i + 1}: {kind}: {r.message[:90]}')
                    failures += 1
                    if failures == 3:
                        break
            complete, partial = bag_health(bag_dir)
            ok = proc.running and client.alive() and partial == 0
            usage = subprocess.run(['df', '-k', str(bag_dir)], capture_output=True,
                                   text=True).stdout.splitlines()[-1].split()
            print(f'  outcomes {kinds}; bags complete {complete}, partial {partial}; '
                  f'disk used {usage[2]} of {usage[1]} KiB; node '
                  f'{"serving" if ok else "BROKEN"}')
            survived.append(('full disk', str(kinds), ok))
            client.node.destroy_node()
    finally:
        rclpy.try_shutdown()
        if mounted:
            subprocess.run(['umount', str(bag_dir)], capture_output=True)

    good = sum(1 for _, _, ok in survived if ok)
    print(f'\nsurvived {good} of {len(survived)} faults')
    return 0 if good == len(survived) else 1


if __name__ == '__main__':
    sys.exit(main())
