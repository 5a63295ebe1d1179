"""Wall time of one pour at the pour's own physics settings against the same pour at the
global settings (config/physics.yaml without its programs section), in the same run.

Starts a projection_server with one worker and an empty bag directory, then alternates
``simulate(pouring, pour, ...)`` at the program's settings and with
``physics(_{solver_iterations: N})`` at the global value, each time at a new cup position
(a few mm apart, so that nothing is cached). Prints the medians and their ratio:

    tools/with_env.sh python bench/pour_speed.py --repeat 5
"""

from __future__ import annotations

from pathlib import Path
import statistics
import sys
import tempfile
import time

import harness


def main() -> int:
    parser = harness.arguments(__doc__, repeat=5)
    parser.add_argument('--angle', type=float, default=2.14)
    parser.add_argument('--time', type=float, default=0.5)
    args = parser.parse_args()
    harness.ros_domain(180, 40)

    import rclpy

    from projection_server.settings import load_settings

    settings = load_settings()
    own = settings.for_projection('pour').physics
    floor = {'solver_iterations': settings.physics.solver_iterations,
             'rate_hz': settings.physics.rate_hz}
    times: dict[str, list[float]] = {'program': [], 'global': []}
    counts: dict[str, list[int]] = {'program': [], 'global': []}
    rclpy.init()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            params = {'bag_dir': Path(tmp), 'projection_workers': 1, 'default_timeout': 600.0}
            with harness.start_node(params, Path(tmp) / 'node.log', stop_timeout=20.0), \
                    harness.client() as client:
                for i in range(args.repeat):
                    position = 0.002 * i
                    for name, options in (('program', '[]'), ('global', _options(floor))):
                        query = (f'make_projection(pouring, pour, [(_, angle, [{args.angle}]), '
                                 f'(_, time, [{args.time}]), (_, position, [{position}])], '
                                 f'{options}, TL), '
                                 'quantity(particles_on(pancake_maker1), N, TL)')
                        start = time.perf_counter()
                        solution = client.once(query, timeout=600.0)
                        times[name].append(time.perf_counter() - start)
                        counts[name].append(int(solution['N']))
    finally:
        rclpy.try_shutdown()
    program, glob = statistics.median(times['program']), statistics.median(times['global'])
    print('pour speed benchmark: one pour through the service, program settings vs global')
    print(f'  settings: angle {args.angle}, hold {args.time} s, {args.repeat} pours each, '
          f'alternating, 1 worker, {harness.machine()} at the end')
    print(f'  program settings (rate {own.rate_hz} Hz, {own.solver_iterations} iterations): '
          f'median {program:.2f} s  runs {harness.listed(times["program"])}  '
          f'on pan {counts["program"]}')
    print(f'  global settings (rate {floor["rate_hz"]} Hz, {floor["solver_iterations"]} '
          f'iterations): median {glob:.2f} s  runs {harness.listed(times["global"])}  '
          f'on pan {counts["global"]}')
    print(f'  speed-up: {glob / program:.2f}x')
    return 0


def _options(physics: dict[str, int]) -> str:
    return '[physics(_{' + ', '.join(f'{k}: {v}' for k, v in physics.items()) + '})]'


if __name__ == '__main__':
    sys.exit(main())
