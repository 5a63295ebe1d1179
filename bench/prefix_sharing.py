"""Table II's pours as trees of forked processes: how much less CPU they take than each pour
run from the start, and whether every pour still gives the same bag and timeline.

Pours from one position step alike until their commands first differ: until the smaller
angle stops tilting or the shorter hold ends. The product's
:func:`~projection_server.simulation.branching.run_tree` steps what they share once and forks
where they part. Each position's pours of the knowledge base's scenario run twice, as whole
projections (monitor, a bag each, timeline):

* **straight**: each with :meth:`~projection_server.simulation.runner.Simulator.run`, in its
  own task of a pool of 2 processes;
* **tree**: one tree per position, in the same pool.

Prints the CPU seconds of both (a tree's summed over all its processes), their ratio, and
whether every leaf's bag is byte for byte its straight run's and its timeline equal. With
``--global``, the pours also run straight at the global settings (``rate_hz`` and
``solver_iterations`` of config/physics.yaml's ``physics`` section, which the pour had
before it had settings of its own): what the pour's settings and the trees save together::

    tools/with_env.sh python bench/prefix_sharing.py
    tools/with_env.sh python bench/prefix_sharing.py --positions 0.0 --global
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
import itertools
import multiprocessing
from pathlib import Path
import pickle
import resource
import sys
import tempfile
import time

import harness

PROGRAM, SCENARIO = 'pour', 'pouring'
_state: dict = {}


def _start(description: dict) -> None:
    from projection_server.simulation.runner import Simulator
    from projection_server.settings import load_settings

    _state['description'] = description
    _state['settings'] = load_settings()
    _state['simulator'] = Simulator()


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    waited = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + waited.ru_utime + waited.ru_stime


def _job(params: dict, physics: dict | None = None):
    from projection_server.simulation.job import Job

    return Job.checked(_state['description'], PROGRAM, params, physics)


def _logged_end(bag: Path, timeline: dict) -> tuple:
    """What a whole projection left: its bag's files and its timeline, but where they are
    (a bag directory named ``bag``, as its file names follow the directory's)."""
    meta = {k: v for k, v in timeline['meta'].items() if k != 'bag'}
    return ({f.name: f.read_bytes() for f in sorted(bag.iterdir())}, {**timeline, 'meta': meta})


def _name(params: dict) -> str:
    return '-'.join(f'{v}' for v in params.values())


def straight(params: dict, physics: dict | None = None) -> tuple[dict, tuple, float]:
    from projection_server.workers.run import project

    start = _cpu()
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / 'bag'
        end = _logged_end(bag, project(_state['simulator'], _job(params, physics),
                                       _state['settings'], bag))
    return params, end, _cpu() - start


def tree(leaves: list[dict]) -> tuple[list[tuple[dict, tuple]], float]:
    from projection_server.simulation.branching import run_tree
    from projection_server.workers.run import timeline_of

    start = _cpu()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        bags = []
        for params in leaves:
            (out / _name(params)).mkdir()
            bags.append(out / _name(params) / 'bag')

        def report(index: int, result, ok: bool) -> None:   # in the leaf's process
            # A finished projection's timeline is made here, from its records, as a
            # worker's tree makes it.
            end = _logged_end(bags[index], timeline_of(result, bags[index])) if ok else result
            (out / f'{_name(leaves[index])}.end').write_bytes(pickle.dumps(end))

        run_tree(_state['simulator'].client, [(_job(p), b) for p, b in zip(leaves, bags)],
                 _state['settings'], report)
        ends = [(p, pickle.loads((out / f'{_name(p)}.end').read_bytes())) for p in leaves]
    return ends, _cpu() - start


def main() -> int:
    from projection_server.reproduce import paper

    parser = harness.arguments(__doc__)
    parser.add_argument('--positions', type=float, nargs='*')
    parser.add_argument('--global', dest='global_', action='store_true',
                        help='also run the pours straight at the global settings')
    args = parser.parse_args()
    positions = args.positions or paper.POUR_POSITIONS
    trees = [[{'angle': a, 'time': t, 'position': x}
              for t, a in itertools.product(paper.POUR_TIMES, paper.POUR_ANGLES)]
             for x in positions]
    with ProcessPoolExecutor(2, multiprocessing.get_context('forkserver'),
                             initializer=_start,
                             initargs=(harness.kb_scenario(SCENARIO),)) as pool:
        started = time.perf_counter()
        jobs = [p for leaves in trees for p in leaves]
        straights = list(pool.map(straight, jobs))
        straight_wall = time.perf_counter() - started
        started = time.perf_counter()
        forked = list(pool.map(tree, trees))
        tree_wall = time.perf_counter() - started
        if args.global_:
            from projection_server.simulation import load_settings

            engine = load_settings().physics
            physics = {'rate_hz': engine.rate_hz, 'solver_iterations': engine.solver_iterations}
            started = time.perf_counter()
            globals_ = list(pool.map(straight, jobs, [physics] * len(jobs)))
            global_wall = time.perf_counter() - started
    expected = {_name(p): end for p, end, _ in straights}
    same = sum(end == expected[_name(p)] for ends, _ in forked for p, end in ends)
    straight_cpu = sum(cpu for _, _, cpu in straights)
    tree_cpu = sum(cpu for _, cpu in forked)
    count = len(straights)
    print('prefix sharing benchmark: pours of one position stepped once where they agree '
          'and forked where their commands part (run_tree), against each run from the start')
    print(f'  settings: {count} whole projections ({len(trees)} positions {list(positions)}, '
          f'{[{k: v for k, v in p.items() if k != "position"} for p in trees[0]]}), '
          "monitor, a bag each and timeline at the program's settings, 2 processes; "
          f'{harness.machine()} at the end')
    print(f'  straight: {straight_cpu:.1f} CPU s ({straight_wall:.1f} s wall)')
    print(f'  tree:     {tree_cpu:.1f} CPU s ({tree_wall:.1f} s wall), '
          f'{straight_cpu / tree_cpu:.2f}x less CPU')
    if args.global_:
        global_cpu = sum(cpu for _, _, cpu in globals_)
        print(f'  straight at the global settings {physics}: {global_cpu:.1f} CPU s '
              f'({global_wall:.1f} s wall), {global_cpu / straight_cpu:.2f}x the straight '
              f'pours, {global_cpu / tree_cpu:.2f}x the trees')
    print(f'  leaves with the bag (byte for byte) and timeline of their straight run: '
          f'{same}/{count}')
    return 0 if same == count else 1


if __name__ == '__main__':
    sys.exit(main())
