"""The cooked pancake's turn at several time steps: the pour, the cook and the six turns of
Table III (cooked) in this process (no node), with what happens to the bonds.

    tools/with_env.sh python bench/cooked_turn.py --turn 240/20 960/80
    tools/with_env.sh python bench/cooked_turn.py --turn 480/40 960/80/0.1 1920/160/0.05
    tools/with_env.sh python bench/cooked_turn.py --cook 960/80 --turn 240/20 --angles 0.1,0.9

The pour (2.14 rad, 0.5 s, centre; the pour's own physics) runs once and is kept in
``--state`` (a JSON file; delete it to pour again; ``--set-pour`` changes the pour's
scenario, and a state poured with other changes is poured again; ``--set`` the batter's
properties in the cook and the turns). The batter it left on the pan cooks ``--time`` seconds
on pancake_maker1 (``wait``) at each ``--cook`` physics (RATE/ITERATIONS), and each cooked
batter is turned at ``--angles`` at each ``--turn`` physics (RATE/ITERATIONS[/ERP], ERP the
error reduction of joints, contacts and friction), as ``reproduce``'s
``table3_cooked`` does. Printed per turn: the outcome (upside_down), the bonds at the start
and at the end, the bonds broken while pushed / lifted / flipped / at rest, the largest
bonded cluster at the end (particles), where the cluster's centroid ends (x, z relative to
where it started), and the largest distance of the spatula's front edge from its path
(``TurnPancake.pose`` at the same time) during the push [mm]. With ``COOKED_TURN_TRACE=1``
each turn also prints, every 0.1 s, the batter's centroid and the height of its lowest and
highest particle, the z component of its up axis (the Kabsch rotation from where it
started), the spatula's position and its contact points, and the bonds.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import tempfile
import time

import numpy as np

import harness

TRACE = os.environ.get('COOKED_TURN_TRACE') == '1'
POUR = {'angle': 2.14, 'time': 0.5, 'position': 0.0}


def _settings(program=None, physics=None):
    """The settings file's (a job applies its program's and its own physics)."""
    from projection_server.settings import load_settings

    return load_settings()


def _run(job, settings, bag, watch=None):
    """Run ``job``; its timeline and projection. ``watch(projection)`` is called after
    every control step."""
    from projection_server.bags import BagWriter
    from projection_server.simulation.runner import Projection, Simulator
    from projection_server.workers.run import timeline_of

    simulator = Simulator()
    try:
        with BagWriter(bag) as writer:
            projection = Projection(simulator.client, job, settings, writer)
            if watch is None:
                projection.advance()
            else:
                physics = projection.physics
                rate = physics.settings.physics.rate_hz
                control = physics.settings.control.steps_per_control
                end = int(np.ceil(projection.task.duration * rate - 1e-9))
                while physics.step_count < end:
                    projection.advance(min(end, physics.step_count + control))
                    watch(projection)
        return timeline_of(projection, bag), projection
    finally:
        simulator.close()


def quantities(timeline):
    return {(name, tuple(args)): value for name, args, value in timeline['quantities']}


def pour(state: Path, bags: Path, changes: dict) -> dict:
    if state.exists():
        kept = json.loads(state.read_text())
        if kept.get('changes', {}) == changes:
            return kept
        print(f'{state} was poured with {kept.get("changes", {})}: pouring again')
    from projection_server.simulation import Job

    d = harness.kb_scenario('pouring')
    harness.set_properties(d['entities'], changes)
    job = Job.checked(d, 'pour', POUR)
    start = time.process_time()
    timeline, _ = _run(job, _settings('pour', {}), bags / 'pour')
    q = quantities(timeline)
    out = {'positions': q[('particles_on_positions', ('pancake_maker1',))],
           'temperatures': q[('particles_on_temperatures', ('pancake_maker1',))],
           'bonds': q[('particles_on_bonds', ('pancake_maker1',))],
           'cpu': time.process_time() - start, 'changes': changes}
    state.write_text(json.dumps(out))
    return out


def scenario(items: str, batter: dict) -> dict:
    j = harness.prolog()
    return j.query_once(f'create_scenario(C), add_to_scenario(C, [{items}, object(pancake_mix, '
                        '_{name: batter1, positions: P, temperatures: T, bonds: B})]), '
                        'scenario:scenario_description(C, D)',
                        {'P': batter['positions'], 'T': batter['temperatures'],
                         'B': batter['bonds']})['D']


def cook(batter: dict, physics: dict, seconds: float, bags: Path, changes: dict) -> dict:
    from projection_server.simulation import Job

    d = scenario('kitchen_env, pancake_maker1', batter)
    _change(d, changes)
    job = Job.checked(d, 'wait', {'duration': seconds}, physics)
    start = time.process_time()
    timeline, _ = _run(job, _settings('wait', {}), bags / f'cook{_tag(physics)}')
    q = quantities(timeline)
    return {'positions': q[('particles_on_positions', ('pancake_maker1',))],
            'temperatures': q[('particles_on_temperatures', ('pancake_maker1',))],
            'bonds': q[('particles_on_bonds', ('pancake_maker1',))],
            'set_fraction': q[('set_fraction', ('batter1',))],
            'cpu': time.process_time() - start}


def _change(d: dict, changes: dict) -> None:
    for entity in d['entities']:
        if entity['name'] == 'batter1':
            entity['properties'].update(changes)


def _tag(physics):
    return (f'{physics.get("rate_hz", 240)}_{physics.get("solver_iterations", "own")}'
            f'_{physics.get("erp", "own")}')


def turn(batter: dict, angle: float, physics: dict, bags: Path, changes: dict) -> dict:
    from projection_server.simulation import Job
    from projection_server.simulation.batter.heat import BatterHeat
    from projection_server.timeline import cooking

    d = scenario('kitchen_env, pr2_robot, pancake_maker1, spatula1', batter)
    _change(d, changes)
    job = Job.checked(d, 'turn_pancake', {'angle': angle}, physics)
    trace = {'broken': {}, 'lag': 0.0}

    def watch(projection):
        physics_, task = projection.physics, projection.task
        heat = next(h for h in physics_.step_hooks if isinstance(h, BatterHeat))
        phase = next((name for name, end in (('push', task.pushed), ('lift', task.levelled),
                                             ('flip', task.flipped)) if physics_.time < end),
                     'rest')
        trace['broken'][phase] = heat.broken
        if phase == 'push':
            c = physics_.client
            position, orientation = c.getBasePositionAndOrientation(task._spatula)
            r = np.array(c.getMatrixFromQuaternion(orientation)).reshape(3, 3)
            edge = np.array(position) + r @ task._edge
            wanted_centre, wanted_q = task.pose(physics_.time)
            rw = np.array(c.getMatrixFromQuaternion(wanted_q)).reshape(3, 3)
            wanted = np.array(wanted_centre) + rw @ task._edge
            trace['lag'] = max(trace['lag'], float(np.linalg.norm(edge - wanted)))
        trace['heat'] = heat
        if TRACE and physics_.step_count % (physics_.settings.physics.rate_hz // 10) == 0:
            from projection_server.timeline import cooking
            x = physics_.particle_positions('batter1')
            x0 = np.asarray(batter['positions'])
            r = cooking.rotation(x0, x)
            c = physics_.client
            sp = c.getBasePositionAndOrientation(task._spatula)[0]
            print(f'    t {physics_.time:.1f} {phase:5} centroid x {100 * x[:, 0].mean():+.1f} '
                  f'y {100 * x[:, 1].mean():+.1f} z {100 * (x[:, 2].mean() - 0.75):.1f} cm '
                  f'(z {100 * (x[:, 2].min() - 0.75):.1f}-{100 * (x[:, 2].max() - 0.75):.1f}) '
                  f'up_z {r[2, 2]:+.2f} spatula x {100 * sp[0]:+.1f} y {100 * sp[1]:+.1f} '
                  f'z {100 * (sp[2] - 0.75):.1f} cm, {len(c.getContactPoints(task._spatula))} '
                  f'contacts, bonds {len(heat.thermal_state().bonds)}', flush=True)

    start = time.process_time()
    timeline, projection = _run(job, _settings('turn_pancake', {}), bags /
                                f'turn{_tag(physics)}_{angle}', watch)
    cpu = time.process_time() - start
    heat = trace['heat']
    x = projection.physics.particle_positions('batter1')
    x0 = np.asarray(batter['positions'])
    state = heat.thermal_state()
    cluster = cooking.largest_cluster(state.bonds, len(x))
    ok = any(f[0] == 'upside_down' for f in timeline['fluents'])
    broken, before = {}, 0
    for phase in ('push', 'lift', 'flip', 'rest'):
        now = trace['broken'].get(phase, before)
        broken[phase], before = now - before, now
    moved = (x[cluster].mean(axis=0) - x0[cluster].mean(axis=0)) if len(cluster) else [0, 0, 0]
    return {'ok': ok, 'bonds0': len(batter['bonds']), 'bonds1': len(state.bonds),
            'broken': broken, 'cluster': len(cluster), 'dx': float(moved[0]),
            'dz': float(moved[2]), 'lag': trace['lag'], 'cpu': cpu}


def _shape(positions) -> tuple[float, float, float]:
    """The spans of the particles' centres along their horizontal principal axes (long,
    short) [m], and the long axis's angle to x [deg, 0-90]."""
    xy = np.asarray(positions, dtype=float)[:, :2]
    xy = xy - xy.mean(axis=0)
    _, axes = np.linalg.eigh(np.cov(xy.T))
    spans = np.ptp(xy @ axes, axis=0)
    return float(spans[1]), float(spans[0]), float(np.degrees(np.arccos(abs(axes[0, 1]))))


def _assignments(items: list[str]) -> dict[str, float]:
    """``NAME=VALUE`` arguments as a dict."""
    return {k: float(v) for k, v in (item.split('=') for item in items)}


def main() -> None:
    parser = harness.arguments(__doc__)
    parser.add_argument('--state', type=Path, default=Path('/tmp/cooked_turn_pour.json'))
    parser.add_argument('--time', type=float, default=6.0)
    parser.add_argument('--cook', nargs='+', default=['240/20'])
    parser.add_argument('--turn', nargs='+', default=['240/20', '960/80'])
    parser.add_argument('--angles', default='0.1,0.3,0.4,0.5,0.7,0.9')
    parser.add_argument('--set', action='append', default=[],
                        help="NAME=VALUE: a property of the batter (cook and turn)")
    parser.add_argument('--set-pour', action='append', default=[],
                        help="[ENTITY.]NAME=VALUE: a property of the mix (or of ENTITY) in "
                             "the pour")
    parser.add_argument('--set-turn', action='append', default=[],
                        help="NAME=VALUE: a property of the batter in the turn only")
    args = parser.parse_args()
    changes = _assignments(args.set)
    turn_changes = {**changes, **_assignments(args.set_turn)}
    angles = [float(a) for a in args.angles.split(',')]
    print(f'# {harness.machine()}; cook {args.time} s at {args.cook}, turn at {args.turn}, '
          f'changes {changes}, in the turn {turn_changes}')
    with tempfile.TemporaryDirectory() as tmp:
        bags = Path(tmp)
        poured = pour(args.state, bags, _assignments(args.set_pour))
        print(f'pour: {len(poured["positions"])} particles on the pan')
        for c in args.cook:
            physics = harness.physics_setting(c)
            cooked = cook(poured, physics, args.time, bags, changes)
            long_, short, heading = _shape(cooked['positions'])
            print(f'cook {c}: set_fraction {cooked["set_fraction"]:.2f}, '
                  f'{len(cooked["bonds"])} bonds, particle centres spanning {100 * long_:.1f} '
                  f'x {100 * short:.1f} cm, the long axis {heading:.0f} deg from the push (x), '
                  f'{cooked["cpu"]:.0f} CPU s', flush=True)
            turned = bags / f'cooked{_tag(physics)}'   # each cook's turns, own bags
            turned.mkdir()
            for t in args.turn:
                outcomes = []
                for angle in angles:
                    r = turn(cooked, angle, harness.physics_setting(t), turned, turn_changes)
                    outcomes.append('ok' if r['ok'] else 'fail')
                    b = r['broken']
                    print(f'  turn {t} {angle}: {outcomes[-1]:4} bonds {r["bonds0"]}->'
                          f'{r["bonds1"]} broken push/lift/flip/rest {b["push"]}/{b["lift"]}/'
                          f'{b["flip"]}/{b["rest"]} cluster {r["cluster"]} '
                          f'dx {100 * r["dx"]:+.1f} dz {100 * r["dz"]:+.1f} cm '
                          f'lag {1000 * r["lag"]:.1f} mm  {r["cpu"]:.0f} CPU s', flush=True)
                print(f'  turn {t}: {" ".join(outcomes)}', flush=True)


if __name__ == '__main__':
    main()
