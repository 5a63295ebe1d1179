"""Fixtures: a real projection_server node in its own process, and real rclpy clients.

tools/run_tests.sh gives each run its own ROS_DOMAIN_ID with loopback-only discovery.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest

NODE_PARAMS = {
    'default_timeout': 5.0,
    'idle_timeout': 2.0,
    'max_engines': 6,
    'max_solutions': 50,
}


def _node_command(name: str, params: dict) -> list[str]:
    cmd = ['projection_server', '--ros-args', '-r', f'__node:={name}']
    for key, value in params.items():
        cmd += ['-p', f'{key}:={value}']
    return cmd


@pytest.fixture(scope='session')
def rclpy_context():
    import rclpy
    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.fixture(scope='session')
def server(rclpy_context, tmp_path_factory):
    """Start the node; yield its name. Its log is kept in the test's tmp dir."""
    name = 'projection_server'
    log = tmp_path_factory.mktemp('node') / 'node.log'
    params = {**NODE_PARAMS, 'bag_dir': str(tmp_path_factory.mktemp('bags'))}
    with open(log, 'w') as out:
        proc = subprocess.Popen(_node_command(name, params), stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)
    try:
        _wait_for_service(f'/{name}/query', proc, log)
        yield f'/{name}'
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode in (0, -signal.SIGINT), log.read_text()


def _wait_for_service(service: str, proc, log, timeout: float = 60.0):
    from projection_interfaces.srv import PrologQuery
    import rclpy
    node = rclpy.create_node('fixture_probe')
    try:
        client = node.create_client(PrologQuery, service)
        deadline = time.monotonic() + timeout
        while not client.wait_for_service(timeout_sec=0.5):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f'node did not come up:\n{log.read_text()}')
    finally:
        node.destroy_node()


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

    def _call(srv_type, service, request, timeout=30.0):
        key = (srv_type, service)
        if key not in clients:
            clients[key] = node.create_client(srv_type, f'{server}/{service}')
            assert clients[key].wait_for_service(timeout_sec=20.0)
        future = clients[key].call_async(request)
        rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
        assert future.done(), f'no answer from {service}'
        return future.result()
    return _call
