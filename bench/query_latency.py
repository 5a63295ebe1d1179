"""Round-trip latency of a trivial Prolog query against a plain std_srvs Trigger.

Starts, in their own processes and a private ROS domain on loopback:
  - the projection_server node, and
  - a minimal rclpy node serving std_srvs/srv/Trigger (the baseline);
then calls each service N times from this process, alternating, and prints
medians, 90th percentiles and their ratio.

    make bench                        # or: tools/with_env.sh python bench/query_latency.py -n 500
"""

from __future__ import annotations

import argparse
import os
import platform
import signal
import statistics
import subprocess
import sys
import time

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
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('-n', type=int, default=300, help='calls per service')
    parser.add_argument('--warmup', type=int, default=30)
    parser.add_argument('--query', default='X = 1')
    args = parser.parse_args()

    os.environ.setdefault('ROS_DOMAIN_ID', str(100 + os.getpid() % 30))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    procs = [subprocess.Popen(['projection_server'], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, start_new_session=True),
             subprocess.Popen([sys.executable, '-c', TRIGGER_SERVER],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)]
    import rclpy
    from projection_interfaces.srv import PrologQuery
    from std_srvs.srv import Trigger
    rclpy.init()
    node = rclpy.create_node('latency_bench')
    try:
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
        node.destroy_node()
        rclpy.try_shutdown()
        for p in procs:
            p.send_signal(signal.SIGINT)
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)

    print('query latency benchmark')
    rmw = os.environ.get('RMW_IMPLEMENTATION', 'default (Fast DDS)')
    print(f'  settings: n={args.n} per service (alternating), warmup={args.warmup}, '
          f'query={args.query!r} in ONCE mode, RMW={rmw}, '
          f'discovery=LOCALHOST, python {platform.python_version()}, {os.cpu_count()} cores')
    tq, line_q = summary('PrologQuery ONCE round trip', q_times)
    tt, line_t = summary('std_srvs/Trigger round trip', t_times)
    print('  ' + line_t)
    print('  ' + line_q)
    print(f'  ratio of medians (query / trigger): {tq / tt:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
