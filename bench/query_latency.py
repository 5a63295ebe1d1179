"""Round-trip latency of a trivial Prolog query against a plain std_srvs Trigger.

Starts, in their own processes and a private ROS domain on loopback:
  - the projection_server node (an empty bag directory; once its worker is warm), and
  - a minimal rclpy node serving std_srvs/srv/Trigger (the baseline);
then calls each service N times from this process, alternating, and prints
medians, 90th percentiles and their ratio.

    make bench                        # or: tools/with_env.sh python bench/query_latency.py -n 500
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
import statistics
import sys
import tempfile
import time

import harness

TRIGGER_SERVER = '''
import rclpy
from rclpy.executors import ExternalShutdownException
from std_srvs.srv import Trigger
rclpy.init()
node = rclpy.create_node('plain_trigger')
node.create_service(Trigger, '~/trigger', lambda req, res: setattr(res, 'success', True) or res)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    node.destroy_node()
    rclpy.try_shutdown()
'''


def call_timed(node, client, request) -> float:
    import rclpy
    start = time.perf_counter()
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=10)
    elapsed = time.perf_counter() - start
    if not future.done():
        raise RuntimeError(f'no answer from {client.srv_name}')
    return elapsed


def summary(name: str, samples: list[float]) -> tuple[float, str]:
    ms = sorted(s * 1e3 for s in samples)
    med = statistics.median(ms)
    p90 = ms[int(0.9 * (len(ms) - 1))]
    return med, f'{name:<34} median {med:7.3f} ms   p90 {p90:7.3f} ms   min {ms[0]:7.3f} ms'


def main() -> int:
    parser = harness.arguments(__doc__)
    parser.add_argument('-n', type=int, default=300, help='calls per service')
    parser.add_argument('--warmup', type=int, default=30)
    parser.add_argument('--query', default='X = 1')
    args = parser.parse_args()

    harness.ros_domain(100)

    import rclpy
    from projection_interfaces.srv import PrologQuery
    from projection_server.client.launcher import NodeProcess
    from std_srvs.srv import Trigger

    rclpy.init()
    try:
        with contextlib.ExitStack() as stack:
            tmp = Path(stack.enter_context(tempfile.TemporaryDirectory()))
            stack.enter_context(harness.start_node({'bag_dir': tmp / 'bags'}, tmp / 'node.log'))
            plain = stack.enter_context(NodeProcess([sys.executable, '-c', TRIGGER_SERVER],
                                                    tmp / 'trigger.log'))
            plain.wait_for_service('/plain_trigger/trigger', Trigger)
            node = rclpy.create_node('latency_bench')
            stack.callback(node.destroy_node)
            query = node.create_client(PrologQuery, '/projection_server/query')
            trigger = node.create_client(Trigger, '/plain_trigger/trigger')
            for c in (query, trigger):
                if not c.wait_for_service(timeout_sec=60):
                    raise RuntimeError(f'{c.srv_name} did not come up')
            q_req = PrologQuery.Request(mode=PrologQuery.Request.ONCE, query=args.query)
            t_req = Trigger.Request()
            for _ in range(args.warmup):
                call_timed(node, query, q_req)
                call_timed(node, trigger, t_req)
            q_times, t_times = [], []
            for _ in range(args.n):  # alternate, so both see the same machine noise
                q_times.append(call_timed(node, query, q_req))
                t_times.append(call_timed(node, trigger, t_req))
    finally:
        rclpy.try_shutdown()

    print('query latency benchmark')
    rmw = os.environ.get('RMW_IMPLEMENTATION', 'default (Fast DDS)')
    print(f'  settings: n={args.n} per service (alternating), warmup={args.warmup}, '
          f'query={args.query!r} in ONCE mode, RMW={rmw}, '
          f'discovery=LOCALHOST, {harness.machine()}')
    tq, line_q = summary('PrologQuery ONCE round trip', q_times)
    tt, line_t = summary('std_srvs/Trigger round trip', t_times)
    print('  ' + line_t)
    print('  ' + line_q)
    print(f'  ratio of medians (query / trigger): {tq / tt:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
