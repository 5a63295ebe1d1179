"""A URDF arm on PyBullet and on MuJoCo, in the same run: the Panda's top grasp and lift of
the egg (bench/robot_loop.py's plan, at 5 N), a whole projection's CPU and the engine's bare
stepping of the same world, and the outcome on each engine.

    tools/with_env.sh python bench/engines_robots.py [--repeat 3]

* ``projection``: the plan projected in this process (world, program, monitor, bag;
  ``workers.run.project``), a fresh world each time, one warm simulator;
* ``bare``: as many engine steps of the same world freshly built, nothing else (MuJoCo's
  ``mj_step`` with the drives' controllers; PyBullet's ``stepSimulation``): the floor under
  the projection's cost;
* ``--rate-hz``: the physics rate (default the configuration's).

Medians of ``--repeat`` x 5 rounds, CPU seconds (``time.process_time``).
"""

from __future__ import annotations

from pathlib import Path
import statistics
import tempfile
import time

import harness
from plan_cost import plan_job

ENGINES = ('pybullet', 'mujoco')
PLAN = ('plan([move_to(egg1, [0, 0, 0.10], [orientation(top), speed(0.5)]), '
        'move_to(egg1, [0, 0, 0], [speed(0.1)]), close_gripper({force}), wait(0.3), '
        'move_by([0, 0, 0.1]), wait(0.5)])')


def outcome(timeline: dict) -> str:
    kinds = {event[0] for event in timeline.get('events', [])}
    return next((k for k in ('break', 'slip', 'lift') if k in kinds), 'other')


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3)
    parser.add_argument('--force', type=float, default=5.0)
    parser.add_argument('--rate-hz', type=int, default=None)
    args = parser.parse_args()
    from projection_server.simulation import Job, load_settings
    from projection_server.simulation.runner import Simulator
    from projection_server.simulation.scenario import parse_scenario
    from projection_server.workers.run import project

    settings = load_settings()
    template = plan_job('[kitchen_env, panda_robot, egg1]', PLAN.format(force=args.force), {})
    extra = {'rate_hz': args.rate_hz} if args.rate_hz else {}
    jobs = {e: Job.checked(template.scenario, 'plan', {}, {'engine': e, **extra},
                           template.plan) for e in ENGINES}
    print(f'# engines_robots: Panda top grasp and lift at {args.force} N, '
          f'{5 * args.repeat} rounds, rate {args.rate_hz or "default"}; {harness.machine()}',
          flush=True)
    simulator = Simulator()
    cpus = {e: [] for e in ENGINES}
    bares = {e: [] for e in ENGINES}
    steps, outcomes = {}, {}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for e, job in jobs.items():   # warm: imports, compiled models, solvers
                project(simulator, job, settings, Path(tmp) / f'warm-{e}')
            for i in range(5 * args.repeat):
                for e, job in jobs.items():   # the engines interleaved: the same load
                    cpu = time.process_time()
                    timeline = project(simulator, job, settings, Path(tmp) / f'{e}-{i}')
                    cpus[e].append(time.process_time() - cpu)
                    outcomes[e] = outcome(timeline)
                    own = job.settings(settings)
                    steps[e] = round(timeline['meta']['duration'] * own.physics.rate_hz)
                    physics = simulator.session(e).build_world(
                        parse_scenario(job.scenario), own, tool_control=True)
                    cpu = time.process_time()
                    physics.step_unmonitored(steps[e])
                    bares[e].append(time.process_time() - cpu)
    finally:
        simulator.close()
    for e in ENGINES:
        cpu, bare = statistics.median(cpus[e]), statistics.median(bares[e])
        print(f'{e}: projection {1e3 * cpu:.1f} ms CPU, bare stepping {1e3 * bare:.1f} ms CPU '
              f'({steps[e]} steps), projection / bare {cpu / bare:.2f}x; outcome '
              f'{outcomes[e]}', flush=True)
    ratio = statistics.median(cpus['pybullet']) / statistics.median(cpus['mujoco'])
    bare = statistics.median(bares['pybullet']) / statistics.median(bares['mujoco'])
    print(f'pybullet / mujoco: projection {ratio:.2f}x, bare {bare:.2f}x', flush=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
