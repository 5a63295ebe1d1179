"""A family of grasps (one position, several forces) run one by one, as a tree in this
process and as a tree under a forked root: CPU a grasp, timelines included.

    tools/with_env.sh python bench/family_cost.py [--repeat 9] [--forces 1,2,...,11]
        [--engine mujoco] [--only 'in process']

The knowledge base's ``grasping``, ``grasp_object`` at the centre, one projection per
force. Each round runs the family every way, in an order that turns round from one round
to the next; CPU seconds of this process and of the processes it waited for
(``RUSAGE_CHILDREN``), medians of ``--repeat`` rounds, and the ratio of each way to the
straight runs in each round:

* ``straight``: :func:`~projection_server.workers.run.project` of each grasp in turn;
* ``in process``: :func:`~projection_server.simulation.branching.run_in_process` (an
  engine whose worlds copy: what a worker does with a tree on MuJoCo);
* ``forked``: :func:`~projection_server.simulation.branching.run_tree` (the tree's root a
  forked process: what a worker does with a tree of PyBullet's, whose groups fork too).

Each way starts after a full collection of this process's garbage and ends with one (its
own garbage is its cost). ``--only``: the ways beside the straight runs. In this process the
forked root's child copies few pages; a worker that has run many projections has more of
them to copy, and after a fork the forking process's own first writes to each page fault
(they were shared): that cost lands on whatever runs next, here the next way.
"""

from __future__ import annotations

import gc
from pathlib import Path
import resource
import statistics
import sys
import tempfile
import time

import harness


def _children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> int:
    parser = harness.arguments(__doc__, repeat=9)
    parser.add_argument('--forces', default=','.join(str(f) for f in range(1, 12)),
                        help='grip forces [N], comma-separated (default 1-11)')
    parser.add_argument('--engine', default='mujoco', help='engine (default mujoco)')
    parser.add_argument('--only', help='ways beside straight, comma-separated')
    args = parser.parse_args()

    from projection_server.settings import load_settings
    from projection_server.simulation import engines
    from projection_server.simulation.branching import run_in_process, run_tree
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Simulator
    from projection_server.workers.run import project, timeline_of

    forces = [float(f) for f in args.forces.split(',')]
    print(f'# family_cost: grasp_object at the centre, forces {args.forces} N, engine '
          f'{args.engine}, rounds {args.repeat}; CPU ms a grasp with its timeline, medians; '
          f'{harness.machine()}', flush=True)
    scenario = harness.kb_scenario('grasping')
    settings = load_settings()
    simulator = Simulator()
    family = [Job.checked(scenario, 'grasp_object', {'force': f, 'position': 0.0},
                          {'engine': args.engine}) for f in forces]
    ways = ['straight', 'forked']
    if engines.get(args.engine).copyable:
        ways.insert(1, 'in process')
    if args.only:
        ways = [w for w in ways if w in ('straight', *args.only.split(','))]
    spent: dict[str, list[float]] = {way: [] for way in ways}
    with tempfile.TemporaryDirectory() as tmp:
        project(simulator, family[0], settings, Path(tmp) / 'warm')

        def run(way: str, round_: int) -> float:
            # A bag's name without spaces: the writer's own fast close is for plain names.
            name = way.replace(' ', '-')
            leaves = [(job, Path(tmp) / f'{name}-{round_}-{i}') for i, job in enumerate(family)]
            made: list[bool] = []

            def report(index, result, ok):
                if ok:
                    timeline_of(result, leaves[index][1])
                made.append(ok)

            gc.collect()   # each way starts clean, and collects its own garbage (below)
            cpu, children = time.process_time(), _children()
            if way == 'straight':
                for job, bag in leaves:
                    project(simulator, job, settings, bag)
            elif way == 'in process':
                run_in_process(simulator, leaves, settings, report)
                assert made == [True] * len(family), made
            else:   # the leaves report in the tree's processes
                assert run_tree(simulator, leaves, settings, report)
            gc.collect()
            return time.process_time() - cpu + _children() - children

        for round_ in range(args.repeat):
            for way in ways if round_ % 2 == 0 else ways[::-1]:
                spent[way].append(run(way, round_))
    simulator.close()
    ms = {way: 1e3 * statistics.median(values) / len(family) for way, values in spent.items()}
    for way in ways:
        ratios = [a / b for a, b in zip(spent['straight'], spent[way])]
        print(f'{way}: {ms[way]:.1f} ms a grasp; straight / this {statistics.median(ratios):.3f} '
              f'(rounds: {harness.listed(ratios)})', flush=True)
    print(f'# {harness.machine()}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
