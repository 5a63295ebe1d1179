"""Do the belief's probabilities come true as often as they say? Calibration of P(ok).

    tools/with_env.sh python bench/calibration.py                 # 33 cells x 16 eggs
    tools/with_env.sh python bench/calibration.py --eggs 4 --samples 10   # a quick look

When the truth *is* the belief, a predicted probability of 0.8 should come true 8 times in
10. Over the closed loop's 33 grasp cells (grasp_object, forces 1-11 N every 1 N x
positions -0.02, 0, 0.02 m) and its belief (egg1's friction uniform(0.2, 0.4),
breaking_force normal(10, 1.5)), each cell's P(ok) (no slip, no break) is predicted by
``outcome_probability/7`` from ``--samples`` worlds of the belief (seed ``--seed``) at the
program's own physics; then each cell grasps ``--eggs`` fresh true eggs of its own, drawn
from the same belief with another seed (``--truth-seed``; cell i takes that seed's worlds
i * eggs to (i + 1) * eggs - 1, so that the executions are independent of each other and
of the prediction's worlds), at 4x the physics rate and 4x the solver iterations, standing
in for the real world.

With ``--physics fine,own`` the same eggs are also grasped at the program's own physics,
the prediction's: that run's calibration is the statistics' alone, so the gap between the
two is the projection's physics against the finer one.

With ``--refine N`` the cells whose prediction from ``--samples`` worlds lies strictly between
0 and 1 are predicted again from N worlds of the same seed (the first ``--samples`` of them
come from the bag cache): a p estimated from few worlds carries its own sampling error,
which the noise floor below does not count, so the cells where the outcome is uncertain
need many worlds before their ECE can be compared with the floor.

Printed, per execution physics: per cell the prediction and the executed frequency; the
Brier score (mean of
(p - y)^2 over the executions); the expected calibration error over 10 equal-width bins of
p (ECE = sum over bins of n_b / n |mean y_b - mean p_b|) beside its noise floor, the ECE of a
perfectly calibrated predictor on the same p's (y resampled ~ Bernoulli(p), ``--resamples``
times: its median and 95th percentile); and a reliability diagram written as a PNG
(``--png``).
"""

from __future__ import annotations

from pathlib import Path
import statistics
import sys
import tempfile
import time

import numpy as np

import harness

FORCES = [float(f) for f in range(1, 12)]
POSITIONS = [-0.02, 0.0, 0.02]
BELIEF = ('scenario_set_property(S, egg1, friction, uniform(0.2, 0.4)), '
          'scenario_set_property(S, egg1, breaking_force, normal(10, 1.5))')
OK = '( \\+ occurs(break, _, TL), \\+ occurs(slip, _, TL) )'
BINS = 10


def say(text: str = '') -> None:
    print(text, flush=True)


def ece(p: np.ndarray, y: np.ndarray, bins: int = BINS) -> float:
    """Expected calibration error of predictions ``p`` against outcomes ``y``."""
    index = np.minimum((p * bins).astype(int), bins - 1)
    total = 0.0
    for b in range(bins):
        mask = index == b
        if mask.any():
            total += mask.sum() / len(p) * abs(y[mask].mean() - p[mask].mean())
    return total


def reliability(p: np.ndarray, y: np.ndarray, floor: np.ndarray, path: Path,
                title: str) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    index = np.minimum((p * BINS).astype(int), BINS - 1)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6, 7), height_ratios=[3, 1],
                                      sharex=True)
    top.plot([0, 1], [0, 1], color='grey', lw=1, ls='--', label='perfectly calibrated')
    xs, ys, counts = [], [], []
    for b in range(BINS):
        mask = index == b
        if mask.any():
            xs.append(p[mask].mean())
            ys.append(y[mask].mean())
            counts.append(int(mask.sum()))
    top.plot(xs, ys, 'o-', color='tab:blue', label='executed frequency')
    for x, v, n in zip(xs, ys, counts):
        top.annotate(str(n), (x, v), textcoords='offset points', xytext=(4, -10), fontsize=7)
    top.set_ylabel('fraction ok at 4x physics')
    top.set_xlim(0, 1)
    top.set_ylim(-0.02, 1.02)
    top.set_title(title, fontsize=9)
    top.legend(loc='upper left', fontsize=8)
    bottom.bar([(b + 0.5) / BINS for b in range(BINS)],
               [int((index == b).sum()) for b in range(BINS)], width=0.9 / BINS,
               color='tab:blue')
    bottom.set_yscale('log')
    bottom.set_ylabel('executions')
    bottom.set_xlabel(f'predicted P(ok), {BINS} bins')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(args, kind: str, physics: dict, predicted: dict, executed: list, seconds: float,
           diagram: bool) -> None:
    """One execution physics' table, scores and (``diagram``) reliability diagram."""
    outcomes: dict[tuple[float, float], list[int]] = {}
    for s in executed:
        outcomes.setdefault((float(s['F']), float(s['P'])), []).append(int(s['Y']))
    p = np.array([predicted[c] for c, ys in outcomes.items() for _ in ys])
    y = np.array([v for ys in outcomes.values() for v in ys], dtype=float)
    say()
    shown = physics or "(the program's own)"
    say(f'  executed at {kind} physics {shown}: {len(y)} grasps in {seconds:.0f} s')
    say('  cell (force N, position m)   predicted P(ok)   executed ok')
    for cell, ys in sorted(outcomes.items()):
        if predicted[cell] not in (0.0, 1.0) or 0 < sum(ys) < len(ys) or \
                (predicted[cell] == 1.0) != (sum(ys) == len(ys)):
            say(f'  {cell[0]:4.0f} {cell[1]:+.2f}                  {predicted[cell]:.3f}'
                f'            {sum(ys)}/{len(ys)}')
    say('  (the other cells: predicted 0 or 1 and executed alike)')
    brier = float(np.mean((p - y) ** 2))
    error = ece(p, y)
    rng = np.random.default_rng(args.seed)
    floor = np.array([ece(p, (rng.random(len(p)) < p).astype(float))
                      for _ in range(args.resamples)])
    floor_brier = np.array([np.mean((p - (rng.random(len(p)) < p)) ** 2)
                            for _ in range(args.resamples)])
    say(f'  Brier score {brier:.4f} (a calibrated predictor on the same p: median '
        f'{np.median(floor_brier):.4f}, 95th percentile {np.percentile(floor_brier, 95):.4f})')
    say(f'  ECE ({BINS} bins) {error:.4f}; noise floor median {np.median(floor):.4f}, 95th '
        f'percentile {np.percentile(floor, 95):.4f}: '
        f'{"within" if error <= np.percentile(floor, 95) else "ABOVE"} the floor')
    if diagram:
        args.png.parent.mkdir(parents=True, exist_ok=True)
        reliability(p, y, floor, args.png,
                    f'33 grasp cells x {args.eggs} fresh eggs at {kind} physics\n'
                    f'predicted from {args.samples} belief worlds'
                    + (f' ({args.refine} where uncertain)' if args.refine > args.samples else '')
                    + f'\nECE {error:.3f} (floor '
                    f'95th pct {np.percentile(floor, 95):.3f}), Brier {brier:.3f}')
        say(f'  reliability diagram: {args.png}')


def main() -> int:
    parser = harness.arguments(__doc__, seed=11)
    parser.add_argument('--samples', type=int, default=30,
                        help='worlds of the belief per cell for the prediction (30)')
    parser.add_argument('--refine', type=int, default=0,
                        help='worlds of the belief for the cells predicted strictly between '
                             '0 and 1 (0: none)')
    parser.add_argument('--eggs', type=int, default=16,
                        help='fresh true eggs per cell, executed at 4x physics (16)')
    parser.add_argument('--truth-seed', type=int, default=2027,
                        help='seed of the true eggs (2027)')
    parser.add_argument('--resamples', type=int, default=2000,
                        help='draws of the noise floor (2000)')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--physics', default='fine',
                        help="execution physics, comma-separated: fine (4x rate and "
                             "iterations), own (the prediction's) (fine)")
    parser.add_argument('--png', type=Path, default=Path('docs/calibration_grasp.png'),
                        help='the reliability diagram of the first --physics')
    args = parser.parse_args()
    harness.ros_domain(180)

    import rclpy

    say(f'calibration: {len(FORCES) * len(POSITIONS)} grasp cells, prediction from '
        f'{args.samples} belief worlds (seed {args.seed}), {args.eggs} fresh eggs a cell '
        f'(seed {args.truth_seed}) at {args.physics} physics; {args.workers} workers; '
        f'{harness.machine()}')
    started = time.perf_counter()
    rclpy.init()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            params = {'bag_dir': str(Path(tmp) / 'bags'), 'projection_workers': args.workers,
                      'default_timeout': 7200.0, 'max_bags': 10_000_000}
            with harness.start_node(params, Path(tmp) / 'node.log', stop_timeout=20.0), \
                    harness.client() as client:
                from projection_server.reproduce.fidelity import reference_physics

                physics = reference_physics(client, 'grasp_object')
                grid = f'[(F, force, {FORCES}), (P, position, {POSITIONS})]'
                t0 = time.perf_counter()
                predicted = {
                    (float(s['F']), float(s['P'])): dict(s['Pr'].pairs)['p']
                    for s in client.all(
                        f'copy_scenario(grasping, S), {BELIEF}, outcome_probability(S, '
                        f'grasp_object, {grid}, [samples({args.samples}), seed({args.seed})],'
                        f' TL, {OK}, Pr)', timeout=3600.0, max_solutions=10_000)}
                uncertain = sorted(c for c, v in predicted.items() if 0.0 < v < 1.0)
                if args.refine > args.samples and uncertain:
                    for force, position in uncertain:
                        (s,) = client.all(
                            f'copy_scenario(grasping, S), {BELIEF}, outcome_probability(S, '
                            f'grasp_object, [(F, force, [{force}]), (P, position, '
                            f'[{position}])], [samples({args.refine}), seed({args.seed})], '
                            f'TL, {OK}, Pr)', timeout=3600.0, max_solutions=10)
                        say(f'  refined {force:g} N {position:+.2f} m: '
                            f'{predicted[(force, position)]:.3f} from {args.samples} worlds, '
                            f'{dict(s["Pr"].pairs)["p"]:.3f} from {args.refine}')
                        predicted[(force, position)] = dict(s['Pr'].pairs)['p']
                predicting = time.perf_counter() - t0
                runs = {}
                for kind in args.physics.split(','):
                    chosen = physics if kind == 'fine' else {}
                    setting = ', '.join(f'{k}: {v}' for k, v in chosen.items())
                    t1 = time.perf_counter()
                    executed = []
                    for index, (force, position) in enumerate(
                            (f, q) for f in FORCES for q in POSITIONS):
                        # eggs of their own for each cell: independent executions
                        first = index * args.eggs
                        executed += client.all(
                            f'copy_scenario(grasping, S), {BELIEF}, make_projection(S, '
                            f'grasp_object, [(F, force, [{force}]), (P, position, '
                            f'[{position}])], [worlds({first}, {first + args.eggs}), '
                            f'seed({args.truth_seed}), physics(_{{{setting}}}), '
                            f'timeout(3600)], TL), ( {OK} -> Y = 1 ; Y = 0 )',
                            timeout=3600.0, max_solutions=10_000)
                    runs[kind] = (chosen, executed, time.perf_counter() - t1)
    finally:
        rclpy.try_shutdown()
    say(f'  predictions: {len(predicted)} cells x {args.samples} worlds'
        + (f', the uncertain ones x {args.refine}' if args.refine > args.samples else '')
        + f' in {predicting:.0f} s')
    for index, (kind, (chosen, executed, seconds)) in enumerate(runs.items()):
        report(args, kind, chosen, predicted, executed, seconds, index == 0)
    say(f'calibration: {time.perf_counter() - started:.0f} s in all; {harness.machine()}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
