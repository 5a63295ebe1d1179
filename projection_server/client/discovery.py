"""A round trip that proves a server has discovered a process's new clients.

Fast DDS matches a service's two topics in each direction on its own. ``wait_for_service``
returns once the *client* has matched the server; the server may not yet have matched the
client's response reader. A response sent then waits 100 ms for that match and is dropped
("failed to send response (timeout)", ros2/rmw_fastrtps#842): the client waits forever.
On a loaded machine this happens to a request sent right after ``wait_for_service``.

A process announces its endpoints in order over one reliable channel, so a ping answered
on a client created *after* the others proves the server has matched those too. A ping is
harmless to repeat, so an unanswered one is sent again.

>>> query = node.create_client(PrologQuery, '/projection_server/query')
>>> assert query.wait_for_service(timeout_sec=10.0)
>>> assert handshake(node, '/projection_server')   # now query.call_async is answered
"""

from __future__ import annotations

import time
from typing import Any, Callable

from std_srvs.srv import Trigger

__all__ = ['handshake', 'request_resending']

FIRST_RESEND = 0.5   # s: a ping is answered in milliseconds once the match is there
LAST_RESEND = 4.0


def request_resending(client: Any, request: Any, timeout: float,
                      wait: Callable[[Any, float], bool]) -> Any:
    """The response to ``request`` (a request safe to repeat), sent again while unanswered;
    None after ``timeout`` seconds. ``wait(future, seconds)`` returns once the future is
    done or the seconds have passed."""
    end = time.monotonic() + timeout
    period = FIRST_RESEND
    while True:
        future = client.call_async(request)
        try:
            if wait(future, max(0.0, min(period, end - time.monotonic()))) and future.done():
                return future.result()
        finally:
            if not future.done():
                client.remove_pending_request(future)
        if time.monotonic() >= end:
            return None
        period = min(2 * period, LAST_RESEND)


def handshake(node: Any, server: str, timeout: float = 10.0,
              wait: Callable[[Any, float], bool] | None = None) -> bool:
    """True once ``server``'s ``~/ping`` answers a client of ``node`` created now, that
    is, once the server has matched every client ``node``'s process created before it.

    ``wait`` as in :func:`request_resending`; by default this spins ``node`` itself, so
    pass one when an executor already spins it.
    """
    if wait is None:
        import rclpy

        def wait(future, seconds):
            rclpy.spin_until_future_complete(node, future, timeout_sec=seconds)
            return future.done()

    probe = node.create_client(Trigger, f'{server.rstrip("/")}/ping')
    try:
        end = time.monotonic() + timeout
        if not probe.wait_for_service(timeout_sec=timeout):
            return False
        return request_resending(probe, Trigger.Request(), max(0.0, end - time.monotonic()),
                                 wait) is not None
    finally:
        node.destroy_client(probe)
