"""A grasp projection's pipeline against its engine's stepping, on PyBullet and MuJoCo, with
what each stage of the pipeline costs.

    tools/with_env.sh python bench/pipeline_engines.py [--repeat 15] [--force 5] [--position 0]

One ``grasp_object`` of the knowledge base's ``grasping`` (912 steps at 240 Hz), in this
process, a fresh world each time, rounds interleaved (engine by engine; in each round every
variant once), CPU time of this process (``time.process_time``), medians of ``--repeat``:

* ``projection``: :meth:`Simulator.run`, the whole projection (world, program, object
  models, monitor, bag);
* ``bare``: the engine's bare stepping (``mj_step``; ``stepSimulation``) of the same world,
  built without the program, for as many steps (bench/engines.py's ``grasp`` figure);
* ``inside``: the engine's steps inside the projection (the same calls, timed one by one,
  less what the timing itself costs):
  a grasp's own physics, which on PyBullet costs more than the bare world's (the pads
  squeeze the egg: more contacts to solve);
* the stages, by subtraction, each variant without one more of them: the monitor's samples
  (poses, gripper, objects, task, bag), the contact aggregation of every step, the object
  models (the egg's shell, its contact reads), the program's per-step hooks (the gantry's
  targets: without them the gripper does not move, so that variant's physics differs);
  what is left is the world's build, the step loop and the engine calls.
"""

from __future__ import annotations

from pathlib import Path
import statistics
import sys
import tempfile
import time

import harness

ENGINES = ('mujoco', 'pybullet')
VARIANTS = ('projection', '-samples', '-aggregation', '-object models', '-program hooks')


def _variant(simulator, job, settings, bag_path: Path, level: int) -> float:
    """CPU seconds of ``job``'s projection without the first ``level`` stages."""
    from projection_server.bags import BagWriter
    from projection_server.simulation.runner import Projection

    with BagWriter(bag_path) as bag:
        cpu = time.process_time()
        projection = Projection(simulator, job, settings, bag)
        physics = projection.physics
        if level >= 1:
            projection.monitor.sample = lambda: None
        if level >= 2:
            physics.step_hooks.remove(projection.monitor.contacts.add_step)
        if level >= 3:
            physics.models.clear()
        if level >= 4:
            physics.step_hooks.clear()
        projection.advance()
        return time.process_time() - cpu


def _inside(simulator, job, settings, bag_path: Path) -> tuple[float, int]:
    """CPU seconds of the engine's steps inside ``job``'s projection, and their number."""
    import mujoco

    from projection_server.bags import BagWriter
    from projection_server.simulation.runner import Projection

    spent = [0.0, 0]
    clock = time.process_time

    def timed(step):
        def call(*args):
            start = clock()
            step(*args)
            spent[0] += clock() - start
            spent[1] += 1
        return call

    with BagWriter(bag_path) as bag:
        projection = Projection(simulator, job, settings, bag)
        physics = projection.physics
        if physics.engine == 'pybullet':
            physics.client.stepSimulation = timed(physics.client.stepSimulation)
            try:
                projection.advance()
            finally:
                del physics.client.stepSimulation   # the bound client's own again
        else:
            raw = mujoco.mj_step
            mujoco.mj_step = timed(raw)
            try:
                projection.advance()
            finally:
                mujoco.mj_step = raw
    return spent[0] - spent[1] * _clock_cost(), spent[1]


def _clock_cost(calls: int = 20_000) -> float:
    """CPU seconds that a pair of ``process_time`` calls adds to a timed step."""
    clock = time.process_time
    start = clock()
    for _ in range(calls):
        clock() - clock()
    return (clock() - start) / calls


def main() -> int:
    parser = harness.arguments(__doc__, repeat=15)
    parser.add_argument('--force', type=float, default=5.0)
    parser.add_argument('--position', type=float, default=0.0)
    parser.add_argument('--engines', default=','.join(ENGINES),
                        help=f'engines to measure, comma-separated (default {",".join(ENGINES)})')
    args = parser.parse_args()

    from projection_server.settings import load_settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Simulator

    import engines

    print(f'# grasp_object force {args.force} N, position {args.position} m; rounds '
          f'{args.repeat}; CPU ms, medians; {harness.machine()}', flush=True)
    scenario = harness.kb_scenario('grasping')
    settings = load_settings()
    simulator = Simulator()
    with tempfile.TemporaryDirectory() as tmp:
        for engine in args.engines.split(','):
            job = Job.checked(scenario, 'grasp_object',
                              {'force': args.force, 'position': args.position},
                              {'engine': engine})
            simulator.run(job, settings, Path(tmp) / f'{engine}-warm')
            rows: dict[str, list[float]] = {name: [] for name in
                                            ('projection', 'bare', 'inside', *VARIANTS[1:])}
            steps = 0
            for i in range(args.repeat):
                cpu = time.process_time()
                projection = simulator.run(job, settings, Path(tmp) / f'{engine}-{i}')
                rows['projection'].append(time.process_time() - cpu)
                steps = projection.physics.step_count
                rows['bare'].append(engines._bare(simulator, job, settings, steps))
                inside, count = _inside(simulator, job, settings, Path(tmp) / f'{engine}-i{i}')
                rows['inside'].append(inside * steps / max(1, count))
                for level, name in enumerate(VARIANTS[1:], 1):
                    rows[name].append(_variant(simulator, job, settings,
                                               Path(tmp) / f'{engine}-{level}-{i}', level))
            ms = {name: 1e3 * statistics.median(values) for name, values in rows.items()}
            print(f'{engine}: projection {ms["projection"]:.1f}, bare {ms["bare"]:.1f} '
                  f'({ms["projection"] / ms["bare"]:.2f}x), engine steps inside '
                  f'{ms["inside"]:.1f} ({ms["projection"] / ms["inside"]:.2f}x); {steps} steps',
                  flush=True)
            chain = ['projection', *VARIANTS[1:]]
            parts = [f'{name[1:]} {ms[before] - ms[name]:.1f}'
                     for before, name in zip(chain, chain[1:])]
            print(f'{engine} stages: ' + ', '.join(parts)
                  + f'; left (build, loop, engine calls) {ms[chain[-1]]:.1f}', flush=True)
    simulator.close()
    print(f'# {harness.machine()}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
