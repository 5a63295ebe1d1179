"""How closely the spatula of ``turn_pancake`` follows its commanded path, per physics step,
at several time steps (in this process, no node).

    tools/with_env.sh python bench/spatula_lag.py --physics 240/20 480/40 960/80 --angles 0.1,0.9

Each turn of the knowledge base's ``turning`` scenario (the jointed pancake) records after
every physics step the distance of the blade's front edge from where ``TurnPancake.pose``
puts it at that time, the angle between the blade's orientation and the commanded one, and
the force of the constraint that moves it. Printed per turn and phase (push, lift, flip):
the largest and the mean distance [mm], the largest angle [deg], the largest force [N];
then the outcome (upside_down).
"""

from __future__ import annotations

import math
from pathlib import Path
import tempfile

import numpy as np

import harness

PHASES = ('push', 'lift', 'flip')


def turn(angle: float, physics: dict, bags: Path) -> dict:
    from projection_server.bags import BagWriter
    from projection_server.settings import load_settings
    from projection_server.simulation import Job
    from projection_server.simulation.programs.turn import SETTLE
    from projection_server.simulation.runner import Projection, Simulator
    from projection_server.workers.run import timeline_of

    job = Job.checked(harness.kb_scenario('turning'), 'turn_pancake', {'angle': angle},
                      physics)
    rows: dict[str, list[tuple[float, float, float, float]]] = {p: [] for p in PHASES}
    simulator = Simulator()
    try:
        bag = bags / f'turn_{physics["rate_hz"]}_{physics["solver_iterations"]}_{angle}'
        with BagWriter(bag) as writer:
            projection = Projection(simulator.client, job, load_settings(), writer)
            sim, task = projection.physics, projection.task
            c = sim.client

            def record() -> None:
                t = sim.time
                if t < SETTLE or t >= task.flipped:
                    return
                phase = next(n for n, end in zip(PHASES, (task.pushed, task.levelled,
                                                            task.flipped)) if t < end)
                position, orientation = c.getBasePositionAndOrientation(task._spatula)
                r = np.array(c.getMatrixFromQuaternion(orientation)).reshape(3, 3)
                wanted_centre, wanted_q = task.pose(t)
                rw = np.array(c.getMatrixFromQuaternion(wanted_q)).reshape(3, 3)
                distance = np.linalg.norm(np.asarray(position) + r @ task._edge
                                          - (np.asarray(wanted_centre) + rw @ task._edge))
                cos = (np.trace(rw.T @ r) - 1.0) / 2.0
                turned = math.degrees(math.acos(min(1.0, max(-1.0, cos))))
                force = float(np.linalg.norm(c.getConstraintState(task._constraint)[:3]))
                rows[phase].append((float(distance), turned, force, t))

            sim.step_hooks.append(record)
            projection.advance()
        timeline = timeline_of(projection, bag)
    finally:
        simulator.close()
    ok = any(f[0] == 'upside_down' for f in timeline['fluents'])
    return {'ok': ok, 'rows': rows}


def main() -> None:
    parser = harness.arguments(__doc__)
    parser.add_argument('--physics', nargs='+', default=['240/20', '480/40', '960/80'])
    parser.add_argument('--angles', default='0.1,0.5,0.9')
    args = parser.parse_args()
    print(f'# {harness.machine()}')
    print('| physics | angle | outcome | ' + ' | '.join(
        f'{p}: max / mean mm, max deg, max N (when)' for p in PHASES) + ' |')
    print('|---|---|---|' + '---|' * len(PHASES))
    with tempfile.TemporaryDirectory() as tmp:
        for angle in (float(a) for a in args.angles.split(',')):
            for text in args.physics:
                r = turn(angle, harness.physics_setting(text), Path(tmp))
                cells = []
                for phase in PHASES:
                    a = np.asarray(r['rows'][phase]) if r['rows'][phase] else np.zeros((1, 4))
                    cells.append(f'{1000 * a[:, 0].max():.1f} / {1000 * a[:, 0].mean():.1f}, '
                                 f'{a[:, 1].max():.1f}, {a[:, 2].max():.0f} '
                                 f'(at {a[a[:, 2].argmax(), 3]:.3f} s)')
                print(f'| {text} | {angle} | {"ok" if r["ok"] else "fail"} | '
                      + ' | '.join(cells) + ' |', flush=True)


if __name__ == '__main__':
    main()
