"""Where a pour's stepping goes: CPU per phase of the pour and contact points per step, with
engine options that are not settings, and whether a saved state continues as the run did.

Bare stepping of the knowledge base's pouring scenario (read from SWI-Prolog) with the
pour's control and step hook, no monitor and no log, in this process:

    tools/with_env.sh python bench/pour_profile.py                  # the pour's settings
    tools/with_env.sh python bench/pour_profile.py --physics '{"solver_iterations": 100}'
    tools/with_env.sh python bench/pour_profile.py --engine '{"enableConeFriction": 0}'
    tools/with_env.sh python bench/pour_profile.py --sleep --contacts
    tools/with_env.sh python bench/pour_profile.py --restore        # saveState/restoreState

Prints per phase (settling in the upright cup, tilting, holding, tilting back, after the
cup is upright) the steps, CPU seconds and milliseconds per step, with ``--contacts`` the
contact points per step between particles, of particles with the cup, and the rest (every
8th step), and the simulated second at which the pour said it had finished.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import platform
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))

from step_convergence import kb_scenario  # noqa: E402


def build(client, scenario, settings, params, engine, sleep):
    import numpy as np

    from projection_server.simulation.programs import get as get_program
    from projection_server.simulation.world import build_world

    physics = build_world(client, scenario, settings)
    if engine:
        client.setPhysicsEngineParameter(**engine)
    task = get_program('pour').create(physics, scenario, params, np.random.default_rng(0))
    if sleep:
        for body in task._particles:
            client.changeDynamics(body, -1,
                                  activationState=client.ACTIVATION_STATE_ENABLE_SLEEPING)
    return physics, task


def advance(physics, task, until: int) -> None:
    control = physics.settings.control.steps_per_control
    while physics.step_count < until:
        if physics.step_count % control == 0:
            task.control(physics)
        physics.step()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--angle', type=float, default=2.14)
    parser.add_argument('--time', type=float, default=0.5)
    parser.add_argument('--position', type=float, default=0.0)
    parser.add_argument('--physics', default='{}',
                        help="settings over the pour's own (JSON, settings.PHYSICS_OPTIONS)")
    parser.add_argument('--engine', default='{}',
                        help='more setPhysicsEngineParameter arguments (JSON)')
    parser.add_argument('--sleep', action='store_true',
                        help="let Bullet deactivate the particles (activationState)")
    parser.add_argument('--contacts', action='store_true')
    parser.add_argument('--restore', action='store_true',
                        help='step 1 s, saveState, step 2 s; restoreState and step the same '
                             '2 s again: are the particles where the first run left them?')
    args = parser.parse_args()

    import numpy as np
    import pybullet

    from projection_server.simulation.physics import bound_client
    from projection_server.simulation.programs.pour import SETTLE
    from projection_server.simulation.scenario import parse_scenario
    from projection_server.settings import load_settings

    scenario = parse_scenario(kb_scenario('pouring'))
    settings = load_settings().for_projection('pour', json.loads(args.physics))
    engine = json.loads(args.engine)
    params = {'angle': args.angle, 'time': args.time, 'position': args.position}
    client = bound_client(pybullet.DIRECT)
    s = settings.physics
    print(f'pour profile: angle {args.angle}, hold {args.time} s, position {args.position}; '
          f'{s.rate_hz} Hz, {s.solver_iterations} iterations, engine {engine or "-"}, '
          f'sleeping {args.sleep}; python {platform.python_version()}, load average '
          f'{os.getloadavg()[0]:.1f}')
    if args.restore:
        rate = s.rate_hz
        states = []
        for restore in (False, True):
            physics, task = build(client, scenario, settings, params, engine, args.sleep)
            advance(physics, task, rate)
            saved = client.saveState()
            advance(physics, task, 3 * rate)
            if restore:
                client.restoreState(saved)
                physics.step_count = rate
                advance(physics, task, 3 * rate)
            states.append(np.array([client.getBasePositionAndOrientation(b)[0]
                                    for b in task._particles]))
        same = np.array_equal(states[0], states[1])
        print(f'  restored at 1 s and stepped to 3 s: identical {same}, largest particle '
              f'distance {np.abs(states[0] - states[1]).max() * 1000:.1f} mm')
        client.disconnect()
        return 0

    start = time.process_time()
    physics, task = build(client, scenario, settings, params, engine, args.sleep)
    built = time.process_time() - start
    ends = [('settle', SETTLE), ('tilt', task.tilted),
            ('hold', task.released), ('back', task.upright), ('after', math.inf)]
    cpu = {name: 0.0 for name, _ in ends}
    steps = {name: 0 for name, _ in ends}
    points = {name: [0, 0, 0] for name, _ in ends}
    particles, cup = set(task._particles), task._cup
    control, log = settings.control.steps_per_control, settings.control.steps_per_log
    phase, finished = 0, None
    for step in range(math.ceil(task.duration * s.rate_hz - 1e-9)):
        while physics.time >= ends[phase][1]:
            phase += 1
        name = ends[phase][0]
        t = time.process_time()
        if step % control == 0:
            task.control(physics)
        physics.step()
        cpu[name] += time.process_time() - t
        steps[name] += 1
        if args.contacts and step % 8 == 0:
            for p in client.getContactPoints():
                kind = (0 if p[1] in particles and p[2] in particles
                        else 1 if cup in (p[1], p[2]) else 2)
                points[name][kind] += 1
        if physics.step_count % log == 0 and task.finished(physics):
            finished = physics.time
            break
    total = time.process_time() - start
    print(f'  {total:.2f} CPU s ({built:.2f} s building), finished at '
          f'{finished if finished is None else round(finished, 3)} s simulated')
    for name, _ in ends:
        line = (f'  {name:6s} {steps[name]:5d} steps {cpu[name]:6.2f} CPU s '
                f'{1000 * cpu[name] / max(steps[name], 1):6.2f} ms/step')
        if args.contacts and steps[name]:
            sampled = math.ceil(steps[name] / 8)
            line += ('  contact points per step: particle-particle {:.0f}, particle-cup '
                     '{:.0f}, other {:.0f}'.format(*(n / sampled for n in points[name])))
        print(line)
    client.disconnect()
    return 0


if __name__ == '__main__':
    sys.exit(main())
