"""What the batter's cohesion, viscosity and heat cost a pour: CPU of the same Table II pour
with the batter's step hooks of this tree, with those of an earlier revision, without the
cohesion and viscosity (surface_tension 0, viscosity 0: the batter before they existed) and
with no batter hooks at all (the floor: Bullet, the pour's control and the monitor's absence),
alternating in this process, at the pour's own physics; then, with ``--cook``, the batter
that the pour leaves on the pan cooks there, with this tree's and the earlier hooks.

    tools/with_env.sh python bench/batter_cost.py --repeat 5
    tools/with_env.sh python bench/batter_cost.py --angle 1.99 --time 0.5 --old 7b89c6c
    tools/with_env.sh python bench/batter_cost.py --cook 0 --whole
    tools/with_env.sh python bench/batter_cost.py --cook 0 --whole --before

Each pour is bare stepping of the pour's world and task as a projection builds them (control,
step hooks and object models; no monitor, no bag), to its end (the batter at rest), or with
``--whole`` the whole projection (its monitor samples and writes a bag). The
variant ``old`` builds the same world with the batter modules (forces, heat, neighbours) of
revision ``--old``, loaded from a copy; ``old`` and ``now`` must step alike (the same steps,
the same particle positions at the end). Printed: per variant the median CPU seconds of a
pour, its steps and milliseconds per step, the medians of the forces' and the heat's hooks'
own CPU per step, and the ratios of the medians. With ``--before`` also the pour as it was
before the batter cohered and heated (no batter hooks, the cup tilted at 2 rad/s without
ramps, 20 solver iterations, the mix's drops held from rolling by a rolling friction of
0.02 m): ``now / before`` is what the batter and the slower pour cost together. With ``--read`` also this
pour with the velocities read from Bullet each step (``now / read``: what taking them from
the positions saves). With
``--rolling`` also the cohesive batter held from rolling that way, at the 100 iterations it
needed (``now / rolling``: what the drops' ``rotational_inertia`` saves).
"""

from __future__ import annotations

import contextlib
import copy
import importlib
import inspect
import math
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile
import time
from unittest import mock

import harness

MODULES = ('neighbours', 'forces', 'heat')


def old_batter(revision: str, into: Path) -> tuple[type, type]:
    """The classes BatterForces and BatterHeat of ``revision``'s batter modules, copied into
    the package ``batter_old`` under ``into``."""
    root = Path(__file__).resolve().parent.parent
    package = into / 'batter_old'
    package.mkdir()
    (package / '__init__.py').write_text('')
    for name in MODULES:
        text = subprocess.run(
            ['git', 'show', f'{revision}:projection_server/simulation/batter/{name}.py'],
            cwd=root, capture_output=True, text=True, check=True).stdout
        (package / f'{name}.py').write_text(
            text.replace('projection_server.simulation.batter.', 'batter_old.'))
    sys.path.insert(0, str(into))
    forces, heat = (importlib.import_module(f'batter_old.{name}') for name in ('forces', 'heat'))
    from projection_server.simulation.batter.heat import BatterHeat

    # Arguments the old hooks do not take are dropped: set_inertia acts only on particles
    # that set, so a pour steps alike, a cook of a batter whose inertia is raised does not.
    newer = set(inspect.signature(BatterHeat).parameters) - set(
        inspect.signature(heat.BatterHeat).parameters)

    class OldHeat(heat.BatterHeat):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **{k: v for k, v in kwargs.items() if k not in newer})

    return forces.BatterForces, OldHeat


def _rolling(scenario: dict) -> dict:
    """``scenario`` with its mix's drops held from rolling by a rolling and spinning
    friction of 0.02 m, as they were before the mix's ``rotational_inertia``."""
    harness.find_entity(scenario['entities'], 'pancake_mix1')['properties'].update(
        rolling_friction=0.02, spinning_friction=0.02, rotational_inertia=1.0)
    return scenario


def run(client, job, settings, hooks, detach=False, whole=False, motion=None):
    """(CPU s, steps, CPU s in the forces' hooks, in the heat's, final positions) of one pour
    (or cook) to its end; the world built with ``hooks`` (forces' and heat's classes), with
    ``detach`` stepped without them, with ``whole`` a whole projection (its monitor samples
    and writes a bag); ``motion``: the pour program's constants to use instead (name:
    value)."""
    from projection_server.bags import BagWriter
    from projection_server.simulation.objects import particle_fluid
    from projection_server.simulation.programs import pour
    from projection_server.simulation.runner import Projection

    with contextlib.ExitStack() as stack:
        for name, value in (motion or {}).items():
            stack.enter_context(mock.patch.object(pour, name, value))
        stack.enter_context(mock.patch.object(particle_fluid, 'BatterForces', hooks[0]))
        stack.enter_context(mock.patch.object(particle_fluid, 'BatterHeat', hooks[1]))
        if whole:
            bag = Path(stack.enter_context(tempfile.TemporaryDirectory())) / 'bag'
            projection = Projection(client, job, settings,
                                    stack.enter_context(BagWriter(bag)))
        else:
            projection = harness.bare_projection(client, job, settings)
        physics, task = projection.physics, projection.task
        settings = physics.settings   # the program's and the job's own, as a worker has them
        spent = [0.0, 0.0]
        for k, hook in enumerate(physics.step_hooks):
            for which, cls in enumerate(hooks):
                if isinstance(hook, cls):
                    def timed(hook=hook, which=which):
                        t = time.process_time()
                        hook()
                        spent[which] += time.process_time() - t
                    physics.step_hooks[k] = timed
        if detach:
            physics.step_hooks = [hook for hook in physics.step_hooks
                                  if getattr(hook, '__name__', '') != 'timed']
        control, log = settings.control.steps_per_control, settings.control.steps_per_log
        finished = getattr(task, 'finished', None)
        end = math.ceil(task.duration * settings.physics.rate_hz - 1e-9)
        start = time.process_time()
        if whole:
            projection.advance()
        while physics.step_count < end and not whole:
            if physics.step_count % control == 0:
                task.control(physics)
            physics.step()
            if finished is not None and physics.step_count % log == 0 and finished(physics):
                break
        cpu = time.process_time() - start
    ids = [body for fluid in physics.fluids.values() for body in fluid.body_ids]
    at = [client.getBasePositionAndOrientation(body)[0] for body in ids]
    return cpu, physics.step_count, spent[0], spent[1], at


def cooking(params: dict, seconds: float):
    """The job of a cook: the batter that the pour ``params`` leaves on pancake_maker1 (from
    a whole projection of it), on the heated pancake maker for ``seconds``."""
    from projection_server.bags import BagWriter
    from projection_server.settings import load_settings
    from projection_server.simulation import Job
    from projection_server.simulation.runner import Projection, Simulator
    from projection_server.workers.run import timeline_of

    simulator = Simulator()
    try:
        bag = Path(tempfile.mkdtemp()) / 'pour'
        with BagWriter(bag) as writer:
            projection = Projection(simulator.client, Job.checked(
                harness.kb_scenario('pouring'), 'pour', params), load_settings(), writer)
            projection.advance()
        q = {(name, tuple(a)): v for name, a, v in timeline_of(projection, bag)['quantities']}
    finally:
        simulator.close()
    on = {key: q[(f'particles_on_{key}', ('pancake_maker1',))]
          for key in ('positions', 'temperatures', 'bonds')}
    scenario = harness.prolog().query_once(
        'create_scenario(C), add_to_scenario(C, [kitchen_env, pancake_maker1, '
        'object(pancake_mix, _{name: batter1, positions: P, temperatures: T, bonds: B})]), '
        'scenario:scenario_description(C, D)',
        {'P': on['positions'], 'T': on['temperatures'], 'B': on['bonds']})['D']
    return Job.checked(scenario, 'wait', {'duration': seconds}), len(on['positions'])


def main() -> int:
    parser = harness.arguments(__doc__, repeat=5)
    parser.add_argument('--angle', type=float, default=2.14)
    parser.add_argument('--time', type=float, default=0.5)
    parser.add_argument('--position', type=float, default=0.0)
    parser.add_argument('--cook', type=float, default=4.0,
                        help='seconds that the poured batter then cooks (0: no cook)')
    parser.add_argument('--whole', action='store_true',
                        help='each pour a whole projection: its monitor samples, writes a bag')
    parser.add_argument('--before', action='store_true',
                        help='also the pour as it was before the batter cohered and heated '
                             '(no batter hooks, the cup at 2 rad/s without ramps, the mix '
                             'held from rolling by rolling friction)')
    parser.add_argument('--rolling', action='store_true',
                        help='also the pour of the batter held from rolling by rolling '
                             'friction, at the 100 solver iterations it needed')
    parser.add_argument('--read', action='store_true',
                        help="also the pour with the particles' velocities read from Bullet "
                             'each step, as before they were taken from the positions')
    parser.add_argument('--old', default='7b89c6c',
                        help='the revision of the batter modules to compare with')
    args = parser.parse_args()

    from projection_server.settings import load_settings
    from projection_server.simulation import Job
    from projection_server.simulation.batter import BatterForces
    from projection_server.simulation.batter.heat import BatterHeat
    from projection_server.simulation.runner import Simulator

    now = (BatterForces, BatterHeat)
    old = old_batter(args.old, Path(tempfile.mkdtemp()))
    params = {'angle': args.angle, 'time': args.time, 'position': args.position}
    settings = load_settings().for_projection('pour')
    cohesive = Job.checked(harness.kb_scenario('pouring'), 'pour', params)
    mix = harness.kb_scenario('pouring')
    harness.find_entity(mix['entities'], 'pancake_mix1')['properties'].update(
        surface_tension=0.0, viscosity=0.0)
    # name: (job, hooks, hooks detached, the pour's motion)
    variants = {'now': (cohesive, now, False, None), 'old': (cohesive, old, False, None),
                'without': (Job.checked(mix, 'pour', params), now, False, None),
                'floor': (cohesive, now, True, None)}
    if args.before:
        # The pour before the batter coheres or heats: no batter hooks, the cup tilted at
        # 2 rad/s with no ramps, the 20 solver iterations the pour had then, and the mix's
        # rolling and spinning friction of 0.02 m that held its drops from rolling then.
        variants['before'] = (Job.checked(_rolling(copy.deepcopy(mix)), 'pour', params,
                                          {'solver_iterations': 20}),
                              now, True,
                              {'TILT_RATE': 2.0, 'TILT_ACCEL': 1e9})
    if args.read:
        class ReadForces(BatterForces):
            # Forgetting the last step's positions makes particle_state ask Bullet for the
            # velocities, as it did before 08441e0.
            def __call__(self):
                self._physics.particles_moved()
                super().__call__()

        variants['read'] = (cohesive, (ReadForces, BatterHeat), False, None)
    if args.rolling:
        # The cohesive batter as it was until its drops slid by their inertia: held from
        # rolling by rolling friction, poured with the 100 solver iterations it needed.
        variants['rolling'] = (Job.checked(_rolling(harness.kb_scenario('pouring')), 'pour',
                                           params, {'solver_iterations': 100}),
                               now, False, None)
    p = harness.find_entity(harness.kb_scenario('pouring')['entities'],
                            'pancake_mix1')['properties']
    s = settings.physics
    print(f'batter cost: pour {params}, {s.rate_hz} Hz, {s.solver_iterations} iterations; '
          f"the knowledge base's mix: surface_tension {p['surface_tension']}, "
          f"viscosity {p['viscosity']}; old: the batter modules of {args.old}; "
          f"{'whole projections' if args.whole else 'bare stepping'}; "
          f'{args.repeat} rounds; {harness.machine()}', flush=True)
    simulator = Simulator()
    rows = {name: [] for name in variants}
    ends = {}
    for round_ in range(args.repeat):
        for name, (job, hooks, detach, motion) in variants.items():
            cpu, steps, forces, heat, at = run(simulator.client, job, settings, hooks, detach,
                                               args.whole, motion)
            rows[name].append((cpu, steps, forces, heat))
            ends.setdefault(name, (steps, at))
            print(f'  round {round_ + 1} {name:8s} {cpu:6.2f} s CPU, {steps} steps, '
                  f'{1000 * cpu / steps:.2f} ms a step (forces {1000 * forces / steps:.2f}, '
                  f'heat {1000 * heat / steps:.2f})', flush=True)
    if args.cook > 0:
        cook, count = cooking(params, args.cook)
        print(f'cook: the {count} particles the pour leaves on the pan, {args.cook} s on it',
              flush=True)
        variants.update({'cook now': (cook, now, False, None),
                         'cook old': (cook, old, False, None)})
        for name in ('cook now', 'cook old'):
            rows[name] = []
        for round_ in range(args.repeat):
            for name in ('cook now', 'cook old'):
                job, hooks, detach, _ = variants[name]
                cpu, steps, forces, heat, at = run(simulator.client, job, settings, hooks,
                                                   whole=args.whole)
                rows[name].append((cpu, steps, forces, heat))
                ends.setdefault(name, (steps, at))
                print(f'  round {round_ + 1} {name:8s} {cpu:6.2f} s CPU, {steps} steps, '
                      f'{1000 * cpu / steps:.2f} ms a step (forces {1000 * forces / steps:.2f},'
                      f' heat {1000 * heat / steps:.2f})', flush=True)
    simulator.close()
    if args.cook > 0:
        print(f'cook old and now step alike: {ends["cook old"] == ends["cook now"]}')
    print(f'old and now step alike: {ends["old"] == ends["now"]} '
          f'({ends["old"][0]} and {ends["now"][0]} steps)')
    med = {name: [statistics.median(r[0] for r in rs)]
           + [statistics.median(r[k] / r[1] for r in rs) for k in (0, 2, 3)]
           for name, rs in rows.items()}
    for name, (cpu, step, forces, heat) in med.items():
        print(f'{name:8s} median {cpu:.2f} s a pour, {1000 * step:.2f} ms a step, of which '
              f'forces {1000 * forces:.3f} ms, heat {1000 * heat:.3f} ms')

    def ratio(a, b, k):
        return f'{med[a][k] / med[b][k]:.2f}x'

    print(f'now / old: pour {ratio("now", "old", 0)}, step {ratio("now", "old", 1)}, '
          f'forces {ratio("now", "old", 2)}, heat {ratio("now", "old", 3)}, forces + heat '
          f'{(med["now"][2] + med["now"][3]) / (med["old"][2] + med["old"][3]):.2f}x')
    if args.cook > 0:
        print(f'cook now / old: {ratio("cook now", "cook old", 0)}, step '
              f'{ratio("cook now", "cook old", 1)}, forces '
              f'{ratio("cook now", "cook old", 2)}, heat {ratio("cook now", "cook old", 3)}')
    for a in ('now', 'old'):
        print(f'{a} / without: pour {ratio(a, "without", 0)}, step {ratio(a, "without", 1)}; '
              f'{a} / floor: step {ratio(a, "floor", 1)}')
    if args.before:
        print(f'now / before: pour {ratio("now", "before", 0)}, step '
              f'{ratio("now", "before", 1)} ({med["now"][0]:.2f} against '
              f'{med["before"][0]:.2f} s a pour)')
    if 'read' in med:
        print(f'now / read: pour {ratio("now", "read", 0)}, step {ratio("now", "read", 1)}, '
              f'forces {ratio("now", "read", 2)}')
    if 'rolling' in med:
        print(f'now / rolling: pour {ratio("now", "rolling", 0)}, step '
              f'{ratio("now", "rolling", 1)} ({med["now"][0]:.2f} against '
              f'{med["rolling"][0]:.2f} s a pour)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
