"""Cost of the egg's contact-pressure model against the physics step it follows.

Runs the knowledge base's grasping scenario (``grasp_object``, Table I forces and positions)
in this process, timing every ``stepSimulation`` and every ``EggShell.after_step`` separately,
once with the model's cached pad solutions (as projections run) and once solving every pad
contact in every step (the model before the cache). Prints the medians over the grasps of
the model's time per step, the step's time per step and their ratio.

    tools/with_env.sh python bench/egg_model_cost.py [--forces 1,5,9] [--positions 0,0.02]
"""

from __future__ import annotations

import statistics
import time

import harness


def grasp(client, scenario: dict, force: float, position: float,
          cache: bool) -> tuple[float, float]:
    """Seconds of stepping and of the egg model per physics step of one grasp."""
    from projection_server.simulation import Job, load_settings

    settings = load_settings()
    job = Job.checked(scenario, 'grasp_object', {'force': force, 'position': position})
    projection = harness.bare_projection(client, job, settings)
    physics, task = projection.physics, projection.task
    (egg,) = physics.models
    # EggShell takes ``cache`` only when the world builder makes it: no public switch after.
    egg.cache = cache
    physics.models = []   # stepped and measured separately below
    steps = int(task.duration * settings.physics.rate_hz)
    stepping = model = 0.0
    for step in range(steps):
        if step % settings.control.steps_per_control == 0:
            task.control(physics)
        t0 = time.perf_counter()
        physics.step()   # the engine's step, without the model
        t1 = time.perf_counter()
        egg.after_step(physics)
        t2 = time.perf_counter()
        stepping += t1 - t0
        model += t2 - t1
    return stepping / steps, model / steps


def main() -> None:
    from projection_server.simulation import load_settings
    from projection_server.simulation.runner import Simulator

    parser = harness.arguments(__doc__)
    parser.add_argument('--forces', default='1,3,5,7,9,11')
    parser.add_argument('--positions', default='-0.02,0,0.02')
    args = parser.parse_args()
    cells = [(float(f), float(p)) for p in args.positions.split(',')
             for f in args.forces.split(',')]
    scenario = harness.kb_scenario('grasping')
    settings = load_settings()
    simulator = Simulator()
    print(f'{len(cells)} grasps, {settings.physics.rate_hz} Hz, '
          f'{settings.physics.solver_iterations} solver iterations')
    for cache in (True, False):
        rows = [grasp(simulator.client, scenario, f, p, cache) for f, p in cells]
        step = statistics.median(r[0] for r in rows) * 1e6
        model = statistics.median(r[1] for r in rows) * 1e6
        ratios = statistics.median(r[1] / r[0] for r in rows)
        label = 'cached pad solutions' if cache else 'every step solved'
        print(f'{label:>22}: model {model:7.1f} us/step, step {step:7.1f} us/step, '
              f'model/step {ratios:.2f} (median of {len(rows)})')
    simulator.close()


if __name__ == '__main__':
    main()
