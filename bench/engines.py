"""PyBullet and MuJoCo side by side: a grasp's cost, Table I cell by cell, and the certified
robust choice over the 33 grasp cells, on each engine in the same run.

    tools/with_env.sh python bench/engines.py [--repeat 3] [--seed 1] [--skip-robust]

* ``grasp``: one ``grasp_object`` (5 N, centre) in this process, a fresh world each time:
  the whole projection (world, program, monitor, bag; :class:`Simulator.run`) and the
  engine's bare stepping of the same world for as many steps (MuJoCo's ``mj_step``;
  PyBullet's ``stepSimulation``), medians of ``--repeat`` x 5;
* ``table I``: the paper's query through a node of 2 workers, bags cold, on each engine
  and on MuJoCo at 4x its own rate and iterations (120 Hz and 100: 480 and 400); cell by
  cell, with the agreements;
* ``robust``: ``robust_parametrization/7`` of bench/robust_choice.py (egg1's friction
  uniform(0.2, 0.4), breaking_force normal(10, 1.5)) on each engine, each round a fresh
  copy of the scenario (nothing cached), medians of ``--repeat``.
"""

from __future__ import annotations

import json
from pathlib import Path
import statistics
import sys
import tempfile
import time

import harness
from robust_choice import BELIEF, GRID, OK

ENGINES = ('pybullet', 'mujoco')
OUTCOME = '( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip ; O = ok )'
# robust_choice's cells and belief, on the engine asked for
ROBUST = (BELIEF + ', '
          'robust_parametrization(S, grasp_object, {grid}, [seed({seed}), '
          'physics(_{{engine: {engine}}})], TL, {ok}, B)')


def grasp_costs(repeat: int) -> dict[str, dict[str, float]]:
    from projection_server.settings import load_settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Simulator

    scenario = harness.kb_scenario('grasping')
    settings = load_settings()
    simulator = Simulator()
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for engine in ENGINES:
            job = Job.checked(scenario, 'grasp_object', {'force': 5.0, 'position': 0.0},
                              {'engine': engine})
            walls, cpus, bares = [], [], []
            simulator.run(job, settings, Path(tmp) / f'{engine}-warm')
            for i in range(5 * repeat):
                start, cpu = time.perf_counter(), time.process_time()
                projection = simulator.run(job, settings, Path(tmp) / f'{engine}-{i}')
                walls.append(time.perf_counter() - start)
                cpus.append(time.process_time() - cpu)
                bares.append(_bare(simulator, job, settings, projection.physics.step_count))
            out[engine] = {'wall_ms': 1e3 * statistics.median(walls),
                           'cpu_ms': 1e3 * statistics.median(cpus),
                           'bare_ms': 1e3 * statistics.median(bares),
                           'steps': projection.physics.step_count}
    simulator.close()
    return out


def _bare(simulator, job, settings, steps: int) -> float:
    """CPU seconds of ``steps`` bare engine steps of ``job``'s freshly built world."""
    from projection_server.simulation.scenario import parse_scenario

    own = job.settings(settings)
    physics = simulator.session(own.physics.engine).build_world(
        parse_scenario(job.scenario), own)
    step = physics.step_unmonitored
    cpu = time.process_time()
    step(steps)
    return time.process_time() - cpu


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3, seed=1)
    parser.add_argument('--skip-robust', action='store_true')
    args = parser.parse_args()
    harness.ros_domain(200)
    print(f'# engines: {", ".join(ENGINES)}; rounds {args.repeat}; {harness.machine()}',
          flush=True)
    costs = grasp_costs(args.repeat)
    for engine, c in costs.items():
        print(f'grasp {engine}: projection {c["wall_ms"]:.1f} ms wall, {c["cpu_ms"]:.1f} ms '
              f'CPU; bare stepping {c["bare_ms"]:.1f} ms CPU ({c["steps"]} steps)', flush=True)
    print(f'grasp pybullet / mujoco: projection '
          f'{costs["pybullet"]["cpu_ms"] / costs["mujoco"]["cpu_ms"]:.2f}x, bare '
          f'{costs["pybullet"]["bare_ms"] / costs["mujoco"]["bare_ms"]:.2f}x', flush=True)

    import rclpy

    from projection_server.reproduce.paper import GRASP_FORCES, GRASP_POSITIONS, TABLE_I
    from projection_server.settings import load_settings

    rclpy.init()
    try:
        with harness.node_with_client(workers=2) as (c, bags):
            tables = {}
            forces = ', '.join(map(str, GRASP_FORCES))
            positions = ', '.join(map(str, GRASP_POSITIONS))
            own = load_settings().for_projection('grasp_object', {'engine': 'mujoco'}).physics
            fine = (f'_{{engine: mujoco, rate_hz: {4 * own.rate_hz}, '
                    f'solver_iterations: {4 * own.solver_iterations}}}')   # MuJoCo's own, 4x
            for name, physics in (('pybullet', '_{}'), ('mujoco', '_{engine: mujoco}'),
                                  ('mujoco 4x', fine)):
                query = (f'make_projection(grasping, grasp_object, [(F, force, [{forces}]), '
                         f'(P, position, [{positions}])], [physics({physics})], TL), '
                         f'{OUTCOME}')
                seconds, count, solutions = harness.timed(c, bags, query, timeout=3600)
                tables[name] = {(s['F'], s['P']): s['O'] for s in solutions}
                print(f'table I {name}: {seconds:.2f} s ({count} projections)', flush=True)
            print('| force N | position m | paper | ' + ' | '.join(tables) + ' |')
            print('|---|---|---|' + '---|' * len(tables))
            for position in GRASP_POSITIONS:
                for force in GRASP_FORCES:
                    key = (force, position)
                    print(f'| {force} | {position} | {TABLE_I[key]} | '
                          + ' | '.join(t[key] for t in tables.values()) + ' |')
            agree = {(a, b): sum(tables[a][k] == (TABLE_I[k] if b == 'paper' else tables[b][k])
                                 for k in TABLE_I)
                     for a, b in (('pybullet', 'paper'), ('mujoco', 'paper'),
                                  ('mujoco', 'pybullet'), ('mujoco 4x', 'mujoco'))}
            print('agreement: ' + '; '.join(f'{a} with {b} {n}/18' for (a, b), n in
                                             agree.items()), flush=True)
            if not args.skip_robust:
                rows: dict[str, list[tuple[float, int]]] = {e: [] for e in ENGINES}
                for round_ in range(args.repeat):
                    seed = args.seed + round_
                    for engine in ENGINES:
                        seconds, count, (robust,) = harness.timed(
                            c, bags, ROBUST.format(grid=GRID, seed=seed, engine=engine,
                                                   ok=OK), timeout=3600)
                        rows[engine].append((seconds, count))
                        best = {str(k): v for k, v in robust['B'].pairs}
                        print(f'round {round_} robust {engine}: {seconds:.2f} s ({count} '
                              f'projections): force {robust["F"]} N, position {robust["P"]}, '
                              f'certified {best["certified"]} (seed {seed})', flush=True)
                harness.medians(rows)
    finally:
        rclpy.try_shutdown()
    print(f'# {harness.machine()}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
