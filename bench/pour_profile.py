"""Where a pour's stepping goes: CPU per phase of the pour and contact points per step, with
engine options that are not settings, and whether a saved state continues as the run did.

Bare stepping of the knowledge base's pouring scenario (from the server's Prolog), its
world and task as a projection builds them, with the pour's control and step hook, no
monitor and no log, in this process:

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

import json
import math
import sys
import time

import harness


def build(client, job, settings, engine, sleep):
    """The pour's world and task as a projection builds them, its monitor detached; then
    ``engine``'s options and, with ``sleep``, particles that Bullet may deactivate."""
    projection = harness.bare_projection(client, job, settings)
    if engine:
        client.setPhysicsEngineParameter(**engine)
    if sleep:
        for body in particles(projection.physics):
            client.changeDynamics(body, -1,
                                  activationState=client.ACTIVATION_STATE_ENABLE_SLEEPING)
    return projection


def particles(physics) -> list[int]:
    """The bodies of every particle fluid."""
    return [body for fluid in physics.fluids.values() for body in fluid.body_ids]


def advance(physics, task, until: int) -> None:
    control = physics.settings.control.steps_per_control
    while physics.step_count < until:
        if physics.step_count % control == 0:
            task.control(physics)
        physics.step()


def main() -> int:
    parser = harness.arguments(__doc__)
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

    from projection_server.settings import load_settings
    from projection_server.simulation import Job
    from projection_server.simulation.programs.pour import SETTLE
    from projection_server.simulation.runner import Simulator

    params = {'angle': args.angle, 'time': args.time, 'position': args.position}
    job = Job.checked(harness.kb_scenario('pouring'), 'pour', params)
    settings = load_settings().for_projection('pour', json.loads(args.physics))
    engine = json.loads(args.engine)
    simulator = Simulator()
    client = simulator.client
    s = settings.physics
    print(f'pour profile: angle {args.angle}, hold {args.time} s, position {args.position}; '
          f'{s.rate_hz} Hz, {s.solver_iterations} iterations, engine {engine or "-"}, '
          f'sleeping {args.sleep}; {harness.machine()}')
    if args.restore:
        rate = s.rate_hz
        states = []
        for restore in (False, True):
            projection = build(client, job, settings, engine, args.sleep)
            physics, task = projection.physics, projection.task
            advance(physics, task, rate)
            saved = client.saveState()
            advance(physics, task, 3 * rate)
            if restore:
                client.restoreState(saved)
                physics.step_count = rate
                advance(physics, task, 3 * rate)
            states.append(np.array([client.getBasePositionAndOrientation(b)[0]
                                    for b in particles(physics)]))
        same = np.array_equal(states[0], states[1])
        print(f'  restored at 1 s and stepped to 3 s: identical {same}, largest particle '
              f'distance {np.abs(states[0] - states[1]).max() * 1000:.1f} mm')
        simulator.close()
        return 0

    start = time.process_time()
    projection = build(client, job, settings, engine, args.sleep)
    physics, task = projection.physics, projection.task
    built = time.process_time() - start
    ends = [('settle', SETTLE), ('tilt', task.tilted),
            ('hold', task.released), ('back', task.upright), ('after', math.inf)]
    cpu = {name: 0.0 for name, _ in ends}
    steps = {name: 0 for name, _ in ends}
    points = {name: [0, 0, 0] for name, _ in ends}
    fluid = set(particles(physics))
    cup = physics.body(next(projection.scenario.of_class('cup')).name).body_id
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
                kind = (0 if p[1] in fluid and p[2] in fluid
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
    simulator.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
