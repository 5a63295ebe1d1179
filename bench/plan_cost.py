"""What a plan costs: the README's grasp plan against the built-in grasp_object, and the
new tasks' projections (the Panda's grasp, a push off the table, a mesh glass lifted).

    tools/with_env.sh python bench/plan_cost.py [--repeat 5]

In this process, one projection after the other on one warm simulator, each the whole
pipeline of a worker (world, program, monitor, bag, timeline: workers.run.project). Each
round runs every task once, in turn, so that the machine's load falls on all alike; the
figures are the medians of the rounds, wall and CPU seconds, and the plan-grasp's ratio to
the built-in grasp of the same cell (the goal: at most 1.2x). Also printed: each task's
simulated seconds, and its projection's cost per simulated second.
"""

from __future__ import annotations

from pathlib import Path
import statistics
import sys
import tempfile
import time

import harness

GRASP_PLAN = '''plan([move_to(egg1, [P - 0.09, 0, 0], [orientation(side(0)), speed(2.0)]),
                      move_to(egg1, [P, 0, 0], [speed(0.15)]),
                      close_gripper(F), wait(0.3), move_by([0, 0, 0.1], [speed(0.1)]),
                      wait(1.0)])'''
TASKS = {
    'panda grasp': ('[kitchen_env, panda_robot, egg1]', '''plan([
        move_to(egg1, [0, 0, 0.10], [orientation(top), speed(0.5)]),
        move_to(egg1, [0, 0, 0], [speed(0.1)]), close_gripper(5), wait(0.3),
        move_by([0, 0, 0.1]), wait(1.0)])'''),
    'push off the table': ('''[kitchen_env, pr2_robot, entity(box1, rigid_object,
        _{shape: box, size_x: 0.05, size_y: 0.05, size_z: 0.05, mass: 0.2, friction: 0.4,
          pose: _{xyz: [0.45, 0.0, 0.745]}})]''', '''plan([close_gripper(10),
        move_to(box1, [-0.09, 0, 0], [orientation(side(0)), speed(1.0)]),
        move_by([0.3, 0, 0], [speed(0.1)]), move_by([-0.1, 0, 0])])'''),
    'mesh glass lifted': ('[kitchen_env, pr2_robot, glass1]', '''plan([open_gripper,
        move_to(glass1, [0, -0.12, 0.03], [orientation(side(pi/2)), speed(1.0),
                                           angular_speed(3)]),
        move_to(glass1, [0, 0, 0.03], [speed(0.1)]), close_gripper(10), wait(0.3),
        move_by([0, 0, 0.1]), wait(1.0)])'''),
}


def plan_job(members: str, plan: str, params: dict[str, float]) -> object:
    """The job of ``plan`` in a scenario of ``members`` (KB names or entity terms), as
    make_projection makes it: the plan's template from Prolog's plan_template/3."""
    from projection_server.simulation import Job

    janus = harness.prolog()
    # The plan's variables are its parameters, named as in the text. (janus answers every
    # variable not named _...; and a lambda without free variables copies none of them.)
    answer = janus.query_once(
        'create_scenario(_S), term_string(_Ms, MT), add_to_scenario(_S, _Ms), '
        'scenario:scenario_description(_S, D), '
        'term_string(plan(_Steps), PT, [variable_names(_Vs)]), '
        'maplist([_N=_V, _N-_V]>>true, _Vs, _Pairs), '
        'plan:plan_template(_Steps, _Pairs, T), delete_scenario(_S)',
        {'MT': members, 'PT': plan})
    return Job.checked(answer['D'], 'plan', params, None, answer['T'])


def main() -> int:
    args = harness.arguments(__doc__, repeat=5).parse_args()
    from projection_server.simulation import Job, load_settings
    from projection_server.simulation.runner import Simulator
    from projection_server.workers.run import project

    settings = load_settings()
    cell = {'force': 5.0, 'position': 0.0}
    jobs = {'built-in grasp_object': Job.checked(harness.kb_scenario('grasping'),
                                                 'grasp_object', cell),
            'README grasp plan': plan_job('[kitchen_env, pr2_robot, egg1]', GRASP_PLAN, {
                'F': cell['force'], 'P': cell['position']})}
    jobs.update({name: plan_job(members, plan, {}) for name, (members, plan) in TASKS.items()})
    print(f'plan_cost: {args.repeat} rounds of {len(jobs)} projections, one warm simulator; '
          f'{harness.machine()}')
    simulator = Simulator()
    walls: dict[str, list[float]] = {name: [] for name in jobs}
    cpus: dict[str, list[float]] = {name: [] for name in jobs}
    simulated: dict[str, float] = {}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for name, job in jobs.items():   # warm: first projections pay imports
                project(simulator, job, settings, Path(tmp) / f'warm-{len(simulated)}')
                simulated[name] = 0.0
            for round_ in range(args.repeat):
                for k, (name, job) in enumerate(jobs.items()):
                    bag = Path(tmp) / f'{round_}-{k}'
                    wall, cpu = time.perf_counter(), time.process_time()
                    timeline = project(simulator, job, settings, bag)
                    walls[name].append(time.perf_counter() - wall)
                    cpus[name].append(time.process_time() - cpu)
                    simulated[name] = timeline['meta']['duration']
    finally:
        simulator.close()
    print(f'{"task":24} {"wall s":>8} {"CPU s":>8} {"simulated s":>12} {"CPU per sim s":>14}')
    for name in jobs:
        wall, cpu = statistics.median(walls[name]), statistics.median(cpus[name])
        print(f'{name:24} {wall:8.3f} {cpu:8.3f} {simulated[name]:12.2f} '
              f'{cpu / simulated[name]:14.3f}')
    ratios = [p / b for p, b in zip(cpus['README grasp plan'], cpus['built-in grasp_object'])]
    print(f'plan grasp / built-in grasp, CPU, median of {args.repeat} rounds: '
          f'{statistics.median(ratios):.2f}x (rounds: {harness.listed(ratios)}); goal 1.2x')
    return 0


if __name__ == '__main__':
    sys.exit(main())
