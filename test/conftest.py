"""Fixtures: a real projection_server node in its own process, and real rclpy clients.

tools/run_tests.sh gives each run its own ROS_DOMAIN_ID with loopback-only discovery, and
runs the suite in two processes (pytest-xdist); each process has a domain of its own.
"""

from __future__ import annotations

import os
import threading
import time

import pytest

# The process's index under pytest-xdist ('gw0' -> 0); None when pytest runs alone.
_WORKER = os.environ.get('PYTEST_XDIST_WORKER')
if _WORKER is not None:
    # The run's domain plus the index (tools/run_tests.sh leaves room for it): nodes of
    # the same name in the two processes never see each other. Set before rclpy starts,
    # and inherited by every node and script a test starts.
    os.environ['ROS_DOMAIN_ID'] = str(int(os.environ.get('ROS_DOMAIN_ID', '0'))
                                      + int(_WORKER.removeprefix('gw')))

# Files whose tests share a process: the Ray backend's look at the machine's Ray actors.
SAME_PROCESS = {'test_ray_backend.py': 'ray', 'test_ray_service.py': 'ray'}


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """With ``--dist loadfile`` (tools/run_tests.sh) a file's tests run in one process, in
    their order (its module fixtures, a test that runs first), and so do the
    :data:`SAME_PROCESS` files together."""
    if config.getvalue('dist') != 'loadfile':
        return None
    from xdist.scheduler import LoadFileScheduling

    class _Files(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = super()._split_scope(nodeid)
            return SAME_PROCESS.get(path.rsplit('/', 1)[-1], path)

    return _Files(config, log)


NODE_PARAMS = {
    'default_timeout': 5.0,
    'idle_timeout': 5.0,
    'max_engines': 6,
    'max_solutions': 50,
}


@pytest.fixture(scope='session')
def rclpy_context():
    import rclpy
    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.fixture(scope='session')
def server(rclpy_context, tmp_path_factory):
    """Start the node; yield its name. Its log is kept in the test's tmp dir. Under
    pytest-xdist the processes' nodes share one bag directory: a projection one made is not
    made again by the other (the bag store is safe across processes)."""
    from projection_server.client.launcher import node_command
    from test.nodes import running_node

    name = 'projection_server'
    log = tmp_path_factory.mktemp('node') / 'node.log'
    if _WORKER is None:
        bags = tmp_path_factory.mktemp('bags')
    else:   # beside the processes' own temporary directories
        bags = tmp_path_factory.getbasetemp().parent / 'session_bags'
        bags.mkdir(exist_ok=True)
    params = {**NODE_PARAMS, 'bag_dir': str(bags)}
    with running_node(name, node_command(name, params), log) as fqn:
        yield fqn


@pytest.fixture(scope='session')
def node(rclpy_context):
    """One client node for the session: a new node per test would pay DDS discovery."""
    import rclpy
    n = rclpy.create_node(f'test_client_{os.getpid()}')
    yield n
    n.destroy_node()


@pytest.fixture(scope='session')
def client(server):
    from projection_server.client import PrologClient
    c = PrologClient(server)
    assert c.wait_for_server(20.0)
    yield c
    c.close()


@pytest.fixture(scope='session')
def call(server, node):
    """call(srv_type, 'query', request) -> response, straight over the service."""
    import rclpy

    from projection_server.client.discovery import handshake
    clients = {}
    # Tests call from several threads at once; rclpy's executor may be spun by one thread
    # at a time ("generator already executing"), so they take turns in short slices, and
    # a response that arrives during another thread's slice completes its future there.
    spinning = threading.Lock()

    def _call(srv_type, service, request, timeout=30.0):
        key = (srv_type, service)
        with spinning:
            if key not in clients:
                clients[key] = node.create_client(srv_type, f'{server}/{service}')
                assert clients[key].wait_for_service(timeout_sec=20.0)
                assert handshake(node, server, 20.0), f'{server} did not discover {service}'
            future = clients[key].call_async(request)
        deadline = time.monotonic() + timeout
        while not future.done() and time.monotonic() < deadline:
            with spinning:
                if not future.done():
                    rclpy.spin_until_future_complete(node, future, timeout_sec=0.05)
        assert future.done(), f'no answer from {service}'
        return future.result()
    return _call
