"""What a projection costs beyond its physics: the full pipeline against bare Bullet stepping.

Runs the same projections twice in one process, alternating:

* **pipeline**: what a worker and the node do for one projection: build the world, run the
  program with the object models, monitor, write the MCAP bag, make the timeline from the
  samples in memory, and store it in Prolog (``timeline_create/2``, as ``translate/2``
  does), with a warm simulator (:class:`projection_server.simulation.runner.Simulator`);
* **floor**: the same world and program as the projection builds them, its monitor
  detached, stepped bare (and once more with the object models, to tell their cost from
  the logging's; :func:`harness.floor`): ``stepSimulation`` and, for each
  body with an object model (the egg), one contact query per step, and the program's own
  per-step commands and end (the pour's cup follows its path every step and the pour ends
  once the batter is at rest); nothing else (no object model computations, no
  monitoring, no bag).

The floor is also stepped with just the engine queries that the log and the object models
need, and nothing done with their answers beyond telling which pad touches the egg: each
step the contact points of every moving body and, where the egg is touched, its pose and
the states of the touching gripper's pad links; each monitoring sample the poses of the
moving bodies and particles, their links' states, the grippers' joints and the contact
points of every body. That is what no
implementation of the monitor and the egg's shell in this process can avoid; what is left
of the goal's ratio beyond it is the budget of all the pipeline's Python on those answers.

Prints the medians per program, the split of the pipeline into its parts (and of its time
beyond the floor: object models, monitoring and log, the engine queries, translation,
Prolog), the ratio pipeline / floor, of wall time and of the CPU time of this process (on a
machine shared with other work, CPU time is the steadier measure of what the pipeline
itself costs), and that Python budget at the goal's ratio against what the Python costs.
Scenarios come from the knowledge base (``grasping``, ``pouring``).

    tools/with_env.sh python bench/pipeline_overhead.py --repeat 3
"""

from __future__ import annotations

import os
from pathlib import Path
import statistics
import sys
import tempfile
import time

import harness

GRASPS = [{'force': f, 'position': p} for p in (-0.02, 0.0, 0.02) for f in (1, 5, 11)]
POURS = [{'angle': 1.99, 'time': 0.5, 'position': 0.0}]
GOALS = {'grasp_object': 1.3, 'pour': 1.1}   # pipeline / floor


def to_prolog(timeline: dict) -> float:
    """Seconds to store ``timeline`` in Prolog (then it is removed again)."""
    janus = harness.prolog()
    start = time.perf_counter()
    janus.query_once('timeline:timeline_create(D, TL)', {'D': timeline})
    elapsed = time.perf_counter() - start
    janus.query_once('timeline:timeline_exists(TL), timeline:timeline_remove(TL)')
    return elapsed


def pipeline(simulator, job, settings, bag: Path) -> dict[str, float]:
    """One projection as a worker makes it (simulate and log, then the timeline from the
    records), then stored in Prolog: the seconds of each part and the CPU time of all."""
    from projection_server.workers.run import timeline_of

    start, cpu = time.perf_counter(), time.process_time()
    projection = simulator.run(job, settings, bag)
    ran = time.perf_counter()
    timeline = timeline_of(projection, bag)
    translated = time.perf_counter()
    prolog = to_prolog(timeline)
    cpu = time.process_time() - cpu
    return {'total': translated - start + prolog, 'simulate+log': ran - start,
            'translate': translated - ran, 'prolog': prolog, 'cpu': cpu}


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3)
    parser.add_argument('--pours', type=int, default=len(POURS), help='pours per round (0-1)')
    parser.add_argument('--steps-per-log', type=int, default=None,
                        help="physics steps per monitoring sample (default: config's)")
    args = parser.parse_args()

    from projection_server.settings import load_settings, Settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Simulator

    settings = load_settings()
    if args.steps_per_log is not None:   # a thinner (or denser) log, for what it would save
        data = settings.to_dict()
        data['control']['steps_per_log'] = args.steps_per_log
        settings = Settings.from_dict(data)
    jobs = {'grasp_object': [Job.checked(harness.kb_scenario('grasping'), 'grasp_object', p)
                             for p in GRASPS],
            'pour': [Job.checked(harness.kb_scenario('pouring'), 'pour', p)
                     for p in POURS[:args.pours]]}
    simulator = Simulator()
    bare = Simulator()   # a client of its own for the floor
    results: dict[str, dict[str, list[float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for program, group in jobs.items():
            for job in group:   # warm-up: imports, assets, serializers
                pipeline(simulator, job, settings, Path(tmp) / f'warm-{len(os.listdir(tmp))}')
                harness.floor(bare.client, job, settings)
                break
        for r in range(args.repeat):
            for program, group in jobs.items():
                for i, job in enumerate(group):
                    parts = pipeline(simulator, job, settings, Path(tmp) / f'{program}-{r}-{i}')
                    row = results.setdefault(program, {})
                    for name, value in parts.items():
                        row.setdefault(name, []).append(value)
                    for name, models, queries in (('floor', False, False),
                                                  ('models', True, False),
                                                  ('queries', False, True)):
                        wall, cpu, steps = harness.floor(bare.client, job, settings,
                                                         models, queries)
                        if name == 'floor':
                            row.setdefault('steps', []).append(steps)
                        row.setdefault(name, []).append(wall)
                        row.setdefault(f'{name} cpu', []).append(cpu)
    simulator.close()
    bare.close()

    print('pipeline overhead benchmark: full projection pipeline vs bare Bullet stepping')
    print(f'  settings: {len(jobs["grasp_object"])} grasps ({", ".join(map(str, GRASPS[:2]))}'
          f', ...) and {len(jobs["pour"])} pour(s) {POURS[:args.pours]}, each run '
          f'{args.repeat}x both ways, alternating, in one process; a sample every '
          f'{settings.control.steps_per_log} steps; physics from '
          f'config/physics.yaml; {harness.machine()}')
    for program, row in results.items():
        med = {name: statistics.median(values) for name, values in row.items()}
        ratio = statistics.median(t / f for t, f in zip(row['total'], row['floor']))
        cpu_ratio = statistics.median(t / f for t, f in zip(row['cpu'], row['floor cpu']))
        engine = jobs[program][0].settings(settings).physics
        print(f'  {program} ({engine.rate_hz} Hz, {engine.solver_iterations} solver '
              f'iterations): pipeline {med["total"] * 1e3:7.1f} ms (simulate+log '
              f'{med["simulate+log"] * 1e3:.1f}, translate {med["translate"] * 1e3:.1f}, '
              f'prolog {med["prolog"] * 1e3:.1f}), floor {med["floor"] * 1e3:7.1f} ms, '
              f'ratio {ratio:.2f}x (median of {len(row["total"])} pairs); stepping with the '
              f'object models {med["models"] * 1e3:.1f} ms, with the engine queries '
              f'{med["queries"] * 1e3:.1f} ms; CPU time of this process: '
              f'pipeline {med["cpu"] * 1e3:.1f} ms, floor {med["floor cpu"] * 1e3:.1f} ms, '
              f'with the object models {med["models cpu"] * 1e3:.1f} ms, ratio '
              f'{cpu_ratio:.2f}x')
        # Where the pipeline's time beyond the floor goes (medians of the pairs' differences):
        # the object models' computations (stepping with them - floor), monitoring and the
        # log (simulate+log - stepping with the models), the timeline, Prolog.
        models = statistics.median(m - f for m, f in zip(row['models'], row['floor']))
        monitor = statistics.median(s - m for s, m in zip(row['simulate+log'], row['models']))
        asked = statistics.median(q - f for q, f in zip(row['queries'], row['floor']))
        print(f'    beyond the floor: object models {models * 1e3:+.1f} ms, monitoring and '
              f'log {monitor * 1e3:+.1f} ms; the engine queries of both alone '
              f'{asked * 1e3:+.1f} ms; translate {med["translate"] * 1e3:+.1f} ms, '
              f'prolog {med["prolog"] * 1e3:+.1f} ms')
        print(f'    floor with the engine queries of the log and the object models: ratio '
              f'{statistics.median(q / f for q, f in zip(row["queries"], row["floor"])):.2f}x')
        # At the goal's ratio, what is left for the Python on the engine's answers (the
        # object models' computations, contact sums, messages, bag, timeline), per
        # projection and per step, against what that Python costs now.
        goal = GOALS[program]
        budget = statistics.median(goal * f - q for f, q in zip(row['floor'], row['queries']))
        spent = statistics.median(t - q for t, q in zip(row['total'], row['queries']))
        steps = statistics.median(row['steps'])
        print(f'    at the goal of {goal}x: {budget * 1e3:.1f} ms for the pipeline\'s Python '
              f'({budget / steps * 1e6:.1f} us a physics step, {steps:.0f} steps); it '
              f'costs {spent * 1e3:.1f} ms ({spent / steps * 1e6:.1f} us a step)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
