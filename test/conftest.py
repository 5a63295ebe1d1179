"""Fixtures: a real projection_server node in its own process, and real rclpy clients.

tools/run_tests.sh gives each run its own ROS_DOMAIN_ID with loopback-only discovery.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

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
    """Start the node; yield its name. Its log is kept in the test's tmp dir."""
    from projection_server.client.launcher import node_command, NodeProcess
    name = 'projection_server'
    log = tmp_path_factory.mktemp('node') / 'node.log'
    params = {**NODE_PARAMS, 'bag_dir': str(tmp_path_factory.mktemp('bags'))}
    with NodeProcess(node_command(name, params), log) as proc:
        proc.wait_for_service(f'/{name}/query')
        yield f'/{name}'
    assert proc.returncode in (0, -signal.SIGINT), log.read_text()


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
            future = clients[key].call_async(request)
        deadline = time.monotonic() + timeout
        while not future.done() and time.monotonic() < deadline:
            with spinning:
                if not future.done():
                    rclpy.spin_until_future_complete(node, future, timeout_sec=0.05)
        assert future.done(), f'no answer from {service}'
        return future.result()
    return _call
