"""Run a projection_server node in its own process, for the reproduction and the tests.

>>> command = node_command('/projection_server', {'bag_dir': '/tmp/bags', 'max_engines': 4})
>>> with NodeProcess(command, Path('/tmp/node.log')) as proc:   # after rclpy.init()
...     proc.wait_for_service('/projection_server/query')
...     ...                                          # SIGINT on exit, then SIGTERM, SIGKILL

The node's output goes to the log file; errors that say the node did not come up end with
the tail of that log.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
import signal
import subprocess
import time
from typing import Any, NoReturn, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Mapping, Sequence

__all__ = ['LaunchError', 'NodeProcess', 'STARTUP_TIMEOUT', 'node_command']

STARTUP_TIMEOUT = 60.0
LOG_TAIL_CHARS = 2000


class LaunchError(RuntimeError):
    """The node could not be started, or exited or timed out before its service answered."""


def node_command(node: str, params: Mapping[str, object], *,
                 executable: str = 'projection_server') -> list[str]:
    """The command line running ``executable`` as ``node`` (``[/namespace/]name``) with
    ``params`` as ROS parameters (``--ros-args -p key:=value``)."""
    namespace, _, name = node.rstrip('/').rpartition('/')
    cmd = [executable, '--ros-args']
    if namespace:
        cmd += ['-r', f'__ns:={namespace}']
    cmd += ['-r', f'__node:={name}']
    for key, value in params.items():
        cmd += ['-p', f'{key}:={_param_value(value)}']
    return cmd


def _param_value(value: object) -> str:
    # str(True) is 'True'; write YAML's spelling.
    if isinstance(value, bool):
        return 'true' if value else 'false'
    return str(value)


class NodeProcess:
    """A node started with ``command`` in a new session, its output written to ``log_path``.

    As a context manager, it stops the node on exit (see :meth:`stop`).
    """

    def __init__(self, command: Sequence[str], log_path: Path, *,
                 stop_timeout: float = 15.0):
        self.command = list(command)
        self.log_path = log_path
        self.stop_timeout = stop_timeout
        try:
            with open(log_path, 'w') as log:
                # A new session: a Ctrl-C meant for the caller does not reach the node,
                # which the caller stops in its own time.
                self.proc = subprocess.Popen(self.command, stdout=log,
                                             stderr=subprocess.STDOUT,
                                             start_new_session=True)
        except OSError as exc:
            raise LaunchError(f'cannot start {self.command[0]}: {exc}') from exc

    def __enter__(self) -> NodeProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        return self.proc.poll() is None

    @property
    def returncode(self) -> int | None:
        return self.proc.returncode

    def log_tail(self, chars: int = LOG_TAIL_CHARS) -> str:
        try:
            return self.log_path.read_text(errors='replace')[-chars:]
        except OSError as exc:
            return f'(cannot read {self.log_path}: {exc})'

    def wait_for_service(self, service: str, srv_type: Any = None, *,
                         timeout: float = STARTUP_TIMEOUT) -> None:
        """Block until ``service`` (of ``srv_type``, default ``PrologQuery``) is available.

        Needs an initialised rclpy. Raises :class:`LaunchError` with the tail of the log if
        the process exits first or ``timeout`` seconds pass.
        """
        # Imported here, so that node_command and stop need no ROS environment.
        import rclpy
        if srv_type is None:
            from projection_interfaces.srv import PrologQuery
            srv_type = PrologQuery
        probe = rclpy.create_node(f'launcher_probe_{os.getpid()}')
        try:
            client = probe.create_client(srv_type, service)
            deadline = time.monotonic() + timeout
            while not client.wait_for_service(timeout_sec=0.5):
                if not self.running:
                    self._fail(f'the node exited with code {self.returncode} '
                               f'before {service} was available')
                if time.monotonic() > deadline:
                    self._fail(f'{service} was not available after {timeout:g} s')
        finally:
            probe.destroy_node()

    def _fail(self, message: str) -> NoReturn:
        raise LaunchError(f'{message}; the end of {self.log_path}:\n{self.log_tail()}')

    def stop(self, timeout: float | None = None) -> int:
        """Stop the node: SIGINT; if it has not exited after ``timeout`` seconds (default
        ``stop_timeout``), SIGTERM to its process group, and 5 s later SIGKILL.

        Returns the exit code.
        """
        timeout = self.stop_timeout if timeout is None else timeout
        self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self._signal_group(signal.SIGTERM)
        try:
            return self.proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self._signal_group(signal.SIGKILL)
        return self.proc.wait()

    def _signal_group(self, sig: signal.Signals) -> None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, sig)
