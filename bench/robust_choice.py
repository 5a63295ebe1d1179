"""A certified robust choice over the closed loop's 33 grasp cells, against the nominal grid
of the same cells in the same round.

    tools/with_env.sh python bench/robust_choice.py [--repeat 3] [--seed 1]

One node with 2 workers and an empty bag directory; each round asks, in turn:

* ``nominal``: the 33 cells (forces 1-11 N every 1 N x positions -0.02, 0, 0.02 m) in the
  one nominal world of the belief, the floor: what choosing without a belief costs;
* ``robust``: ``robust_parametrization/7`` over the same cells for the closed loop's belief
  (egg1's friction uniform(0.2, 0.4), breaking_force normal(10, 1.5)): paired elimination,
  then the 59 fresh worlds that can certify a risk of 5 % at 95 %.

Every query projects a fresh copy of the scenario (each round's belief another seed), so
nothing comes from the cache. Printed: wall seconds (medians of the rounds), the
projections each made (bags), the robust choice and its certificate, and the ratio to the
nominal grid of the same round. The goal: a certified choice within 10 s on 2 cores.
"""

from __future__ import annotations

import statistics

import harness

OK = '( \\+ occurs(break, _, TL), \\+ occurs(slip, _, TL) )'
GRID = '[(F, force, range(1, 11, 1)), (P, position, [-0.02, 0.0, 0.02])]'
NOMINAL = (f'copy_scenario(grasping, S), make_projection(S, grasp_object, {GRID}, TL), '
           f'( {OK} -> O = ok ; O = fail )')
# The closed loop's belief: a fresh copy of the scenario S, egg1's properties uncertain.
BELIEF = ('copy_scenario(grasping, S), '
          'scenario_set_property(S, egg1, friction, uniform(0.2, 0.4)), '
          'scenario_set_property(S, egg1, breaking_force, normal(10, 1.5))')
ROBUST = (f'{BELIEF}, '
          f'robust_parametrization(S, grasp_object, {GRID}, [seed({{seed}})], TL, {OK}, B)')


def main() -> int:
    parser = harness.arguments(__doc__, repeat=3, seed=1)
    args = parser.parse_args()
    harness.ros_domain(170)

    import rclpy

    print(f'# robust_choice: 2 workers, rounds {args.repeat}, seeds {args.seed}..'
          f'{args.seed + args.repeat - 1}; {harness.machine()}', flush=True)
    rclpy.init()
    rows: dict[str, list[tuple[float, int]]] = {'nominal': [], 'robust': []}
    ratios = []
    try:
        with harness.node_with_client(workers=2) as (c, bags):
            for round_ in range(args.repeat):
                seed = args.seed + round_
                t_nominal, n_nominal, _ = harness.timed(c, bags, NOMINAL, timeout=3600)
                t_robust, n_robust, (robust,) = harness.timed(
                    c, bags, ROBUST.format(seed=seed), timeout=3600)
                rows['nominal'].append((t_nominal, n_nominal))
                rows['robust'].append((t_robust, n_robust))
                ratios.append(t_robust / t_nominal)
                best = {str(k): v for k, v in robust['B'].pairs}
                print(f'round {round_}: nominal {t_nominal:.2f} s ({n_nominal} projections); '
                      f'robust {t_robust:.2f} s ({n_robust} projections, {best["worlds"]} '
                      f'choosing worlds, {len(best["equals"])} equals): force {robust["F"]} N, '
                      f'position {robust["P"]}, p {best["p"]:.3f}, low {best["low"]:.4f} over '
                      f'{best["n"]} fresh worlds, certified {best["certified"]} (seed {seed})',
                      flush=True)
    finally:
        rclpy.try_shutdown()

    harness.medians(rows)
    print(f'robust / nominal of the same round: median {statistics.median(ratios):.2f}x '
          f'({harness.listed(ratios)}); goal: a certified choice within 10 s; '
          f'{harness.machine()}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
