"""Run a projection_server node in its own process, for scripts, the reproduction and the
tests.

>>> command = node_command('/projection_server', {'bag_dir': '/tmp/bags', 'max_engines': 4})
>>> with NodeProcess(command, Path('/tmp/node.log')) as proc:   # after rclpy.init()
...     proc.wait_for_service('/projection_server/query')
...     ...                                          # SIGINT on exit, then SIGTERM, SIGKILL

The node's output goes to the log file; errors that say the node did not come up end with
the tail of that log.

The node does not outlive the script, whatever ends it, as ``ros2 launch``'s nodes do not
outlive the launch:

* the block ends (a return, an exception, Ctrl-C): the node is stopped (:meth:`stop`);
* SIGTERM (systemd, ``docker stop``, a supervisor, a CI time limit): inside the block it is
  handled like Ctrl-C, raising :class:`Terminated` (a ``KeyboardInterrupt``), so the block
  ends and stops the node, and the script exits with status 143 if nothing catches it;
* SIGKILL, or any death of the thread that started the node: Linux sends the node SIGTERM
  (its parent-death signal, set up by the node on start), on which it stops its workers
  and exits.

Create the ``NodeProcess`` in the thread that lives as long as the node should (the main
thread, usually): the parent-death signal follows the thread that started the process.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time
from typing import Any, NoReturn, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Mapping, Sequence

__all__ = ['LaunchError', 'NodeProcess', 'STARTUP_TIMEOUT', 'Terminated', 'node_command']

STARTUP_TIMEOUT = 60.0
LOG_TAIL_CHARS = 2000


# The node reads it (projection_server.lifetime.PARENT_ENV; the client imports nothing of
# the server): the pid whose death stops the node.
PARENT_ENV = 'PROJECTION_SERVER_PARENT'


class LaunchError(RuntimeError):
    """The node could not be started, or exited or timed out before its service answered."""


class Terminated(KeyboardInterrupt):
    """The script got SIGTERM inside a :class:`NodeProcess` block (handled like Ctrl-C)."""


def _terminated(signum: int, frame: object) -> None:
    raise Terminated(f'signal {signum}')


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
        self._previous_handler: Any = None
        env = {**os.environ, PARENT_ENV: str(os.getpid())}
        try:
            with open(log_path, 'w') as log:
                # A new session: a Ctrl-C meant for the caller does not reach the node,
                # which the caller stops in its own time.
                self.proc = subprocess.Popen(self.command, stdout=log,
                                             stderr=subprocess.STDOUT, env=env,
                                             start_new_session=True)
        except OSError as exc:
            raise LaunchError(f'cannot start {self.command[0]}: {exc}') from exc

    def __enter__(self) -> NodeProcess:
        # SIGTERM ends the block like Ctrl-C, unless the script handles SIGTERM itself.
        if threading.current_thread() is threading.main_thread() and signal.getsignal(
                signal.SIGTERM) in (signal.SIG_DFL, None):
            self._previous_handler = signal.signal(signal.SIGTERM, _terminated)
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        try:
            self.stop()
        finally:
            if self._previous_handler is not None:
                signal.signal(signal.SIGTERM, self._previous_handler)
                self._previous_handler = None
        if isinstance(exc, Terminated):
            sys.exit(128 + signal.SIGTERM)

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
