"""A Ray cluster of one head and some worker nodes on this machine, on loopback: what the
tests and benchmarks of the ``ray`` backend run against, and a model of the commands that
make a real cluster (``ray start --head`` on one machine, ``ray start --address`` on the
others).

    >>> with LocalCluster(nodes=2, cpus_per_node=2) as cluster:
    ...     backend = RayBackend(bag_dir, workers=2, address=cluster.address)

Each node is a ``ray start --block`` process of its own session; stopping it (SIGTERM to
that process) stops the node's Ray processes, and nothing else on the machine. Token
authentication is off (a cluster of one machine for tests; a real cluster keeps Ray's
default, a token): a process that joins it needs :attr:`LocalCluster.env` in its
environment, because a process that once started a Ray instance of its own is left in
token mode by Ray and would refuse the cluster's calls.
"""

from __future__ import annotations

import os
from pathlib import Path
import shutil
import signal
import socket
import subprocess
import tempfile
import time

from projection_server.errors import ErrorKind, ProjectionError

__all__ = ['LocalCluster']

OBJECT_STORE = 100 * 1024 ** 2   # bytes per node: Ray's minimum is 75 MB


class LocalCluster:
    """``nodes`` Ray nodes (the first is the head) with ``cpus_per_node`` logical CPUs."""

    def __init__(self, nodes: int = 1, cpus_per_node: int = 1, startup_timeout: float = 120.0):
        self.nodes = nodes
        self.cpus_per_node = cpus_per_node
        self.startup_timeout = startup_timeout
        self.port = _free_port()
        self.address = f'127.0.0.1:{self.port}'
        # Short: Ray's socket paths live under it and a Unix socket path has 107 bytes.
        self.temp_dir = Path(tempfile.mkdtemp(prefix='ray'))
        self.env = {'RAY_AUTH_MODE': 'disabled'}
        self._processes: list[subprocess.Popen[bytes]] = []

    def __enter__(self) -> LocalCluster:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def start(self) -> None:
        """Start the head, then the worker nodes, and wait until all have joined.

        Raises:
            ProjectionError: kind ``pool_closed`` with Ray's output if a node cannot start.
        """
        common = ['--block', f'--num-cpus={self.cpus_per_node}', '--num-gpus=0',
                  f'--object-store-memory={OBJECT_STORE}',
                  '--disable-usage-stats']
        try:
            self._launch(['--head', f'--port={self.port}', '--include-dashboard=false',
                          f'--temp-dir={self.temp_dir}', *common], 'head')
            for index in range(1, self.nodes):
                self._launch([f'--address={self.address}', *common], f'worker{index}')
        except BaseException:
            self.stop()
            raise

    def stop(self) -> None:
        """Stop every node this cluster started (worker nodes first)."""
        for process in reversed(self._processes):
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
        for process in reversed(self._processes):
            try:
                process.wait(30.0)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(10.0)
        self._processes.clear()
        shutil.rmtree(self.temp_dir, ignore_errors=True)

    def log(self, name: str) -> str:
        """The output of ``ray start`` for node ``name`` (``head``, ``worker1``...)."""
        try:
            return (self.temp_dir / f'{name}.out').read_text(errors='replace')
        except FileNotFoundError:
            return ''

    def _launch(self, args: list[str], name: str) -> None:
        ray = shutil.which('ray')
        if ray is None:
            raise ProjectionError(ErrorKind.POOL_CLOSED, 'the ray command is not installed')
        with open(self.temp_dir / f'{name}.out', 'wb') as out:
            process = subprocess.Popen([ray, 'start', *args], stdout=out,
                                       stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                       env={**os.environ, **self.env}, start_new_session=True)
        self._processes.append(process)
        self._wait_started(name, process)

    def _wait_started(self, name: str, process: subprocess.Popen[bytes]) -> None:
        """Until ``ray start`` says the node runs (a worker node: that it joined the head)."""
        deadline = time.monotonic() + self.startup_timeout
        while 'Ray runtime started' not in self.log(name):
            if process.poll() is not None:
                raise ProjectionError(ErrorKind.POOL_CLOSED, f'ray node {name} stopped (exit code '
                                      f'{process.returncode}):\n{self.log(name)[-3000:]}')
            if time.monotonic() > deadline:
                raise ProjectionError(ErrorKind.POOL_CLOSED, f'ray node {name} did not start within '
                                      f'{self.startup_timeout:g} s:\n{self.log(name)[-3000:]}')
            time.sleep(0.2)


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]
