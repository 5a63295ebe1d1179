"""A ROS 2 program's ``main``: start a node, spin it, end cleanly, whoever started it.

The node server and the stand-in robot both run as console scripts, by hand or from a
script's :class:`~projection_server.client.launcher.NodeProcess`; they end alike.
"""

from __future__ import annotations

import faulthandler
import os
import signal
import sys
from typing import Callable, TypeVar

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node

from projection_server.lifetime import die_with_parent, PARENT_ENV

__all__ = ['run_node']

N = TypeVar('N', bound=Node)

# A shutdown still running after this many seconds writes every thread's stack to stderr
# (a script's NodeProcess sends SIGTERM after 15 s).
SHUTDOWN_REPORT_AFTER = 10.0


def run_node(program: str, make: Callable[[], N], threads: Callable[[N], int],
             fatal: tuple[type[BaseException], ...], args=None) -> int:
    """Spin the node ``make()`` returns on a multi-threaded executor of ``threads(node)``
    threads until Ctrl-C, SIGTERM or the starting script's end; 1 after an error of
    ``fatal`` (printed as ``program: message``), else 0."""
    parent = os.environ.pop(PARENT_ENV, '')
    # Started by a script's NodeProcess: stop, as on SIGTERM, when that script ends, even by
    # SIGKILL (rclpy's signal handler turns SIGTERM into a shutdown like Ctrl-C's).
    if parent.isdigit() and not die_with_parent(int(parent), signal.SIGTERM):
        return 1
    # A crash (SIGSEGV, SIGABRT) writes every thread's stack to stderr, the node's log.
    faulthandler.enable()
    rclpy.init(args=args)
    node = None
    try:
        node = make()
        executor = MultiThreadedExecutor(num_threads=threads(node))
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except fatal as exc:
        print(f'{program}: {exc}', file=sys.stderr)
        return 1
    finally:
        # Not cancelled: a hang after main's return (atexit, the interpreter's end) is
        # reported too, and a process that has ended reports nothing.
        faulthandler.dump_traceback_later(SHUTDOWN_REPORT_AFTER, exit=False)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
