"""The robust choice's 33 grasp cells in several belief worlds, at several time steps of one
engine: whether the outcomes change with the step, and what a projection costs at each.

    tools/with_env.sh python bench/engine_rates.py [--engine mujoco] [--rates 240,120,60,480]
        [--against pybullet]

In this process, one projection at a time: ``grasp_object`` over bench/robust_choice.py's
cells (forces 1-11 N x positions -0.02, 0, 0.02 m) in the knowledge base's egg and in six
worlds of the closed loop's belief (egg1's friction 0.2, 0.27, 0.34 x breaking force 8.5,
11.5 N), each cell at every rate in turn (``physics(_{rate_hz: R})``: the control and
logging rates stay 60 Hz). Each outcome is read off the timeline (break, else slip, else
ok). Printed: per rate, the cells whose outcome is the first rate's, and the median CPU
milliseconds of a projection with its timeline (``Simulator.run`` and
``translate_records``). With ``--against ENGINE``, each cell also runs on that engine at the
first rate, and the cells the two engines agree on are printed.
"""

from __future__ import annotations

import itertools
from pathlib import Path
import statistics
import tempfile
import time

import harness

FORCES = range(1, 12)
POSITIONS = (-0.02, 0.0, 0.02)
WORLDS = [None] + [(mu, bf) for mu in (0.2, 0.27, 0.34) for bf in (8.5, 11.5)]


def main() -> int:
    parser = harness.arguments(__doc__)
    parser.add_argument('--engine', default='mujoco')
    parser.add_argument('--rates', default='240,120,60,480')
    parser.add_argument('--against', default=None, help='a second engine, at the first rate')
    args = parser.parse_args()
    rates = [int(r) for r in args.rates.split(',')]
    runs = [(args.engine, rate) for rate in rates]
    if args.against:
        runs.append((args.against, rates[0]))

    from projection_server.settings import load_settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Simulator
    from projection_server.timeline.translate import translate_records

    print(f'# engine_rates: {args.engine}, rates {rates} Hz, {len(WORLDS)} worlds x '
          f'{len(FORCES) * len(POSITIONS)} cells; {harness.machine()}', flush=True)
    settings = load_settings()
    simulator = Simulator()
    outcomes: dict[tuple[str, int], list[str]] = {run: [] for run in runs}
    cpu: dict[tuple[str, int], list[float]] = {run: [] for run in runs}
    with tempfile.TemporaryDirectory() as tmp:
        count = 0
        for world in WORLDS:
            scenario = harness.kb_scenario('grasping')
            if world is not None:
                harness.set_properties(scenario['entities'], {
                    'egg1.friction': world[0], 'egg1.breaking_force': world[1]})
            for force, position in itertools.product(FORCES, POSITIONS):
                for engine, rate in runs:
                    job = Job.checked(scenario, 'grasp_object',
                                      {'force': float(force), 'position': position},
                                      {'engine': engine, 'rate_hz': rate})
                    bag = Path(tmp) / f'{count}'
                    count += 1
                    start = time.process_time()
                    projection = simulator.run(job, settings, bag)
                    timeline = translate_records(projection.monitor.records, bag,
                                                 projection.scenario)
                    cpu[(engine, rate)].append(time.process_time() - start)
                    outcomes[(engine, rate)].append(harness.grasp_outcome(timeline))
            print(f'world {world or "kb"}: done', flush=True)
    first = outcomes[runs[0]]
    print(f'\n{"engine":>9} {"rate Hz":>8} {f"same as {runs[0][0]} {runs[0][1]} Hz":>22} '
          f'{"ms a projection":>16}   outcomes (ok/slip/break)')
    for run in runs:
        same = sum(a == b for a, b in zip(outcomes[run], first))
        counts = '/'.join(str(outcomes[run].count(o)) for o in ('ok', 'slip', 'break'))
        print(f'{run[0]:>9} {run[1]:>8} {f"{same}/{len(first)}":>22} '
              f'{1e3 * statistics.median(cpu[run]):>16.1f}   {counts}')
    print(f'# {harness.machine()}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
