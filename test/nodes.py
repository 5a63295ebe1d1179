"""Nodes of a test module's own: a projection_server in its own process (its bag directory,
parameters and remappings the module's), and a caller of its services over DDS."""

from __future__ import annotations

import contextlib
from pathlib import Path
import signal
import time
from typing import Any, Callable, Iterator, Mapping, Sequence


@contextlib.contextmanager
def own_server(name: str, params: Mapping[str, object], tmp_path_factory: Any,
               ros_args: Sequence[str] = ()) -> Iterator[str]:
    """A projection_server node ``name`` with ``params`` (and ``ros_args`` such as
    remappings); yields its fully qualified name once its query service answers, and checks
    that it stopped cleanly."""
    from projection_server.client.launcher import node_command

    log = tmp_path_factory.mktemp(f'{name}_node') / 'node.log'
    with running_node(name, [*node_command(name, params), *ros_args], log) as fqn:
        yield fqn


@contextlib.contextmanager
def running_node(name: str, command: Sequence[str], log: Path) -> Iterator[str]:
    """The node ``name`` that ``command`` starts, its output in ``log``; yields its fully
    qualified name once its query service answers, and checks that it stopped cleanly."""
    from projection_server.client.launcher import NodeProcess

    with NodeProcess(command, log) as proc:
        proc.wait_for_service(f'/{name}/query', timeout=60.0)
        yield f'/{name}'
        stopping = time.monotonic()
    # The log first: a report's tail is what a reader sees.
    assert proc.returncode in (0, -signal.SIGINT), (
        f'{log.read_text()}\n(the end of its log) {name} ended with exit code '
        f'{proc.returncode}, {time.monotonic() - stopping:.1f} s after SIGINT')


@contextlib.contextmanager
def caller(server: str, node: Any) -> Iterator[Callable[..., Any]]:
    """``call(srv_type, 'query', request, timeout)`` -> response, from ``node`` to
    ``server``'s services; its clients are destroyed on exit."""
    import rclpy

    from projection_server.client.discovery import handshake

    clients: dict[str, Any] = {}

    def call(srv_type, service, request, timeout=30.0):
        if service not in clients:
            clients[service] = node.create_client(srv_type, f'{server}/{service}')
            assert clients[service].wait_for_service(timeout_sec=20.0)
            assert handshake(node, server, 20.0), f'{server} did not discover {service}'
        future = clients[service].call_async(request)
        rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
        assert future.done(), f'no answer from {service}'
        return future.result()

    try:
        yield call
    finally:
        for c in clients.values():
            node.destroy_client(c)
