"""What the batter's cohesion and viscosity cost a pour: CPU of the same Table II pour with the
knowledge base's mix against the mix without them (surface_tension 0, viscosity 0: the
batter before they existed), alternating in this process, at the pour's own physics.

    tools/with_env.sh python bench/batter_cost.py --repeat 5
    tools/with_env.sh python bench/batter_cost.py --angle 1.84 --time 1.0

Each pour is bare stepping of the pour's world and task as a projection builds them (control,
step hooks and object models; no monitor, no bag), to its end (the batter at rest). Printed:
per variant the median CPU seconds of a pour, its steps and milliseconds per step, the median
of the batter hook's own CPU per step, and the ratios of the medians.
"""

from __future__ import annotations

import math
import statistics
import time

import harness


def pour(client, job, settings):
    """(CPU s, steps, CPU s inside the batter's step hooks) of one pour to its end."""
    from projection_server.simulation.batter import BatterForces

    projection = harness.bare_projection(client, job, settings)
    physics, task = projection.physics, projection.task
    hooked = [0.0]
    for k, hook in enumerate(physics.step_hooks):
        if isinstance(hook, BatterForces):
            def timed(hook=hook):
                t = time.process_time()
                hook()
                hooked[0] += time.process_time() - t
            physics.step_hooks[k] = timed
    control, log = settings.control.steps_per_control, settings.control.steps_per_log
    end = math.ceil(task.duration * settings.physics.rate_hz - 1e-9)
    start = time.process_time()
    while physics.step_count < end:
        if physics.step_count % control == 0:
            task.control(physics)
        physics.step()
        if physics.step_count % log == 0 and task.finished(physics):
            break
    return time.process_time() - start, physics.step_count, hooked[0]


def main() -> int:
    parser = harness.arguments(__doc__, repeat=5)
    parser.add_argument('--angle', type=float, default=2.14)
    parser.add_argument('--time', type=float, default=0.5)
    parser.add_argument('--position', type=float, default=0.0)
    args = parser.parse_args()

    from projection_server.settings import load_settings
    from projection_server.simulation import Job
    from projection_server.simulation.runner import Simulator

    params = {'angle': args.angle, 'time': args.time, 'position': args.position}
    settings = load_settings().for_projection('pour')
    variants = {}
    for name, change in (('batter', {}), ('without', {'surface_tension': 0.0,
                                                       'viscosity': 0.0})):
        scenario = harness.kb_scenario('pouring')
        mix = harness.find_entity(scenario['entities'], 'pancake_mix1')
        mix['properties'].update(change)
        variants[name] = Job.checked(scenario, 'pour', params)
    mix = harness.find_entity(harness.kb_scenario('pouring')['entities'], 'pancake_mix1')
    s = settings.physics
    print(f'batter cost: pour {params}, {s.rate_hz} Hz, {s.solver_iterations} iterations; '
          f"the knowledge base's mix: surface_tension {mix['properties']['surface_tension']}, "
          f"viscosity {mix['properties']['viscosity']}; {args.repeat} rounds; "
          f'{harness.machine()}', flush=True)
    simulator = Simulator()
    rows = {name: [] for name in variants}
    for round_ in range(args.repeat):
        for name, job in variants.items():
            cpu, steps, hooked = pour(simulator.client, job, settings)
            rows[name].append((cpu, steps, hooked))
            print(f'  round {round_ + 1} {name:8s} {cpu:6.2f} s CPU, {steps} steps, '
                  f'{1000 * cpu / steps:.2f} ms a step (hook {1000 * hooked / steps:.2f})',
                  flush=True)
    simulator.close()
    med = {name: (statistics.median(r[0] for r in rs),
                  statistics.median(r[0] / r[1] for r in rs),
                  statistics.median(r[2] / r[1] for r in rs)) for name, rs in rows.items()}
    for name, (cpu, per_step, hook) in med.items():
        print(f'{name:8s} median {cpu:.2f} s a pour, {1000 * per_step:.2f} ms a step, '
              f'of which the batter hook {1000 * hook:.2f} ms')
    print(f'ratio batter / without: pour {med["batter"][0] / med["without"][0]:.2f}x, '
          f'step {med["batter"][1] / med["without"][1]:.2f}x')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
