"""Where a certified robust choice's wall time goes, end to end through a live node.

    tools/with_env.sh python bench/decision_cost.py [--repeat 3] [--seed 1]
        [--engines mujoco,pybullet,mujoco:240] [--keep DIR] [--before COMMAND]

With ``--before COMMAND`` (an executable that runs a node of other code, e.g. of an earlier
commit installed with ``pip install --prefix``, its ``PYTHONPATH`` and ``AMENT_PREFIX_PATH``
first), a second node of that code asks the same queries, each right after this code's:
the two are measured in the same run, under the same load. Such an executable must start
its node outside the source tree (``cd /tmp`` first): ``python -c`` imports the package of
its working directory before any on ``PYTHONPATH``, and the two nodes would run the same
code. Each node's lines say whether its grasps ran in trees, and after the first round the
two nodes' code versions are printed (from a bag of each), with a warning if they are one.

One node with 2 workers and an empty bag directory, its cost log on
(``PROJECTION_SERVER_COST_LOG``, :mod:`projection_server.workers.cost`); each round asks
bench/engines.py's ``robust_parametrization/7`` over the 33 grasp cells (egg1's friction
uniform(0.2, 0.4), breaking_force normal(10, 1.5)) on each engine, a fresh copy of the
scenario each time (nothing cached), seeds ``--seed`` on. Printed per query, from the log: An engine given as
``ENGINE:RATE`` runs at ``RATE`` Hz instead of its own (``engines`` in config/physics.yaml):
``mujoco:240`` against MuJoCo's own 120 Hz, in the same run.

* ``wall``: the query's wall seconds at the client, and the ``floor``: the sum of the
  projections' :meth:`Simulator.run` CPU seconds in the workers, over 2 workers;
* per projection (medians, ms): ``sim`` (Simulator.run CPU), the worker's CPU beyond it,
  ``timeline`` (its share that makes the timeline), ``queue`` (queued -> sent to a worker),
  ``to worker`` (sent -> the worker starts on it), ``back`` (the worker's answer sent -> the
  node has published the bag and settled the future);
* the node: ``prolog`` (the median gap between the projection Prolog got and the next it
  asked for: storing the timeline, the condition, the choice's bookkeeping), ``waiting``
  (the sum of Prolog's waits for the workers), the node process's CPU seconds;
* ``idle``: the workers' wall-clock seconds without work (2 x wall - their busy time).

Then each query's choice (force, position, certified) and the medians over the rounds.
"""

from __future__ import annotations

import collections
import contextlib
import json
import os
from pathlib import Path
import statistics
import sys
import tempfile

import harness
from engines import GRID, OK, ROBUST


def breakdown(log: Path) -> dict[str, float]:
    """The figures of the cost log ``log`` of one query (see the module doc)."""
    events: dict[str, dict[str, dict]] = collections.defaultdict(dict)
    for line in log.read_text().splitlines():
        e = json.loads(line)
        events[e['event']][e['bag']] = e
    projected, leaves, trees = events['projected'], events['leaf'], events['tree']
    sent, answered, queued = events['sent'], events['answered'], events['queued']
    sims = [p['sim_cpu'] for p in projected.values()]
    timeline = [p['timeline_cpu'] for p in [*projected.values(), *leaves.values()]]
    beyond = [p['cpu'] - p['sim_cpu'] for p in projected.values()]
    # A tree's CPU less its leaves' timelines: its physics (with the forks), shared.
    tree_sim = sum(t['cpu'] - sum(leaves[b]['timeline_cpu'] for b in t['leaves'] if b in leaves)
                   for t in trees.values())
    in_trees = sum(len(t['leaves']) for t in trees.values())
    queue = [sent[b]['t'] - queued[b]['t'] for b in sent if b in queued]
    to_worker = [p['start'] - sent[b]['t'] for b, p in projected.items() if b in sent]
    back = [answered[b]['t'] - p['end'] for b, p in [*projected.items(), *leaves.items()]
            if b in answered]
    waits = sorted(events['waited'].values(), key=lambda w: w['got'])
    gaps = [b['asked'] - a['got'] for a, b in zip(waits, waits[1:])]
    busy: dict[int, float] = collections.defaultdict(float)
    for p in [*projected.values(), *trees.values()]:
        busy[p['pid']] += p['end'] - p['start']
    starts = [w['asked'] for w in waits]
    ends = [w['got'] for w in waits]
    span = max(ends) - min(starts) if starts else 0.0

    def ms(values: list[float]) -> float:
        return 1e3 * statistics.median(values) if values else float('nan')

    return {'projections': len(projected) + len(leaves), 'trees': len(trees),
            'in_trees': in_trees, 'tree_sim': tree_sim,
            'floor': (sum(sims) + tree_sim) / 2, 'sim_sum': sum(sims) + tree_sim,
            'sim': ms(sims), 'beyond': ms(beyond), 'beyond_sum': sum(beyond) + sum(
                leaves[b]['timeline_cpu'] for b in leaves),
            'timeline': ms(timeline), 'queue': ms(queue), 'to_worker': ms(to_worker),
            'back': ms(back), 'back_sum': sum(back), 'prolog': ms(gaps),
            'prolog_sum': sum(gaps), 'waiting': sum(w['got'] - w['asked'] for w in waits),
            'idle': 2 * span - sum(busy.values()), 'span': span}


@contextlib.contextmanager
def start_node(server: str, params: dict, log: Path, executable: str):
    """:func:`harness.start_node` of the node ``executable``."""
    from projection_server.client.launcher import node_command, NodeProcess

    with NodeProcess(node_command(server, params, executable=executable), log) as proc:
        proc.wait_for_service(f'{server}/query')
        harness.wait_warm(proc.proc.pid, params['projection_workers'])
        yield proc


def code_of(bags: Path) -> str | None:
    """The code version in the ``/projection/info`` of a bag in ``bags`` (a node's)."""
    from projection_server.bags import read_bag, TOPICS

    for bag in sorted(bags.iterdir()):
        for _, _, info in read_bag(bag, [TOPICS['info']]):
            return info.code_version
    return None


def report(what: str, seconds: float, f: dict[str, float], robust: dict, best: dict) -> None:
    print(f'{what}: {seconds:.2f} s wall, floor {f["floor"]:.2f} s ({f["projections"]} '
          f'projections, {f["sim_sum"]:.1f} CPU s of Simulator.run); force {robust["F"]} N, '
          f'position {robust["P"]}, certified {best["certified"]}', flush=True)
    if f['trees']:
        print(f'  {f["in_trees"]} projections in {f["trees"]} trees: {f["tree_sim"]:.1f} CPU s '
              f'of physics and forks, {1e3 * f["tree_sim"] / f["in_trees"]:.0f} ms a projection',
              flush=True)
    print(f'  per projection (median ms): sim {f["sim"]:.0f}, worker beyond sim '
          f'{f["beyond"]:.1f} (timeline {f["timeline"]:.1f}), queue {f["queue"]:.0f}, to worker '
          f'{f["to_worker"]:.1f}, back {f["back"]:.1f}, prolog gap {f["prolog"]:.1f}', flush=True)
    print(f'  sums (s): worker beyond sim {f["beyond_sum"]:.2f}, back {f["back_sum"]:.2f}, '
          f'prolog gaps {f["prolog_sum"]:.2f}, prolog waiting {f["waiting"]:.2f}, workers idle '
          f'{f["idle"]:.2f} of 2 x {f["span"]:.2f}; node CPU {f["node_cpu"]:.2f}', flush=True)


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3, seed=1)
    parser.add_argument('--engines', default='mujoco,pybullet',
                        help='engines, comma-separated; ENGINE:RATE runs ENGINE at RATE Hz '
                             'rather than its own (e.g. mujoco:240)')
    parser.add_argument('--keep', type=Path, help='copy each query\'s cost log here')
    parser.add_argument('--before', help='executable of a node of the code to compare with')
    args = parser.parse_args()
    engines = args.engines.split(',')
    harness.ros_domain(140)
    print(f'# decision_cost: 2 workers, rounds {args.repeat}, seeds {args.seed}..'
          f'{args.seed + args.repeat - 1}, engines {", ".join(engines)}; {harness.machine()}',
          flush=True)

    import rclpy

    rclpy.init()
    codes = ['after', 'before'] if args.before else ['after']
    rows: dict[str, list[tuple[float, int]]] = {f'{e} {c}': [] for e in engines for c in codes}
    figures: dict[str, list[dict[str, float]]] = {name: [] for name in rows}
    choices: dict[str, list[str]] = {name: [] for name in rows}
    try:
        with contextlib.ExitStack() as stack:
            tmp = Path(stack.enter_context(tempfile.TemporaryDirectory()))
            nodes = {}
            for code in codes:
                server = '/projection_server' + ('' if code == 'after' else '_before')
                log = tmp / f'cost-{code}.jsonl'
                os.environ['PROJECTION_SERVER_COST_LOG'] = str(log)   # the node inherits it
                node = stack.enter_context(start_node(
                    server, {'bag_dir': str(tmp / f'bags-{code}'), 'projection_workers': 2,
                             'max_bags': 10_000_000}, tmp / f'node-{code}.log',
                    args.before if code == 'before' else 'projection_server'))
                nodes[code] = (node, stack.enter_context(harness.client(server)), log,
                               tmp / f'bags-{code}')
            for round_ in range(args.repeat):
                seed = args.seed + round_
                for engine in engines:
                    for code in codes if round_ % 2 == 0 else codes[::-1]:   # in turn first
                        node, c, log, bags = nodes[code]
                        name = f'{engine} {code}'
                        log.write_text('')
                        cpu = harness.cpu_seconds(node.proc.pid)
                        physics = engine.replace(':', ', rate_hz: ')
                        seconds, count, (robust,) = harness.timed(
                            c, bags, ROBUST.format(grid=GRID, seed=seed, engine=physics,
                                                   ok=OK), timeout=3600)
                        f = breakdown(log)
                        if args.keep is not None:
                            args.keep.mkdir(parents=True, exist_ok=True)
                            (args.keep / f'{engine}-{code}-{seed}.jsonl').write_text(
                                log.read_text())
                        f['node_cpu'] = harness.cpu_seconds(node.proc.pid) - cpu
                        f['wall'] = seconds
                        rows[name].append((seconds, count))
                        figures[name].append(f)
                        best = {str(k): v for k, v in robust['B'].pairs}
                        choices[name].append(f'{robust["F"]}/{robust["P"]}/{best["certified"]}')
                        report(f'round {round_} {name} seed {seed}', seconds, f, robust, best)
                if round_ == 0 and args.before:
                    versions = {code: code_of(nodes[code][3]) for code in codes}
                    same = versions['after'] == versions['before']
                    print(f'# code versions: after {versions["after"]}, before '
                          f'{versions["before"]}' + ('; THE SAME: both nodes run one code, '
                                                     'and the comparison is of noise'
                                                     if same else ''), flush=True)
    finally:
        rclpy.try_shutdown()
    harness.medians(rows)
    for name, fs in figures.items():
        keys = ('wall', 'floor', 'idle', 'beyond_sum', 'prolog_sum', 'node_cpu')
        print(f'{name}: medians ' + ', '.join(
            f'{k} {statistics.median(f[k] for f in fs):.2f} s' for k in keys)
            + f'; wall / floor {statistics.median(f["wall"] / f["floor"] for f in fs):.2f}; '
            f'choices (force/position/certified) {", ".join(choices[name])}')
    print(f'# {harness.machine()}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
