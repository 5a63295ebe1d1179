"""The projection_server ROS 2 node: a thin layer over :mod:`projection_server.service.queries`.

Services (relative to the node's name, by default ``/projection_server/...``):

- ``~/query`` (projection_interfaces/srv/PrologQuery)
- ``~/next_solution`` (projection_interfaces/srv/PrologNextSolution)
- ``~/finish`` (projection_interfaces/srv/PrologFinish)
- ``~/ping`` (std_srvs/srv/Trigger): liveness, with the number of live queries.

Action: ``~/project`` (projection_interfaces/action/Project): a query with feedback after
each projection, and cancel (:mod:`projection_server.service.project_action`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import json
import logging
import os
from pathlib import Path
import sys
import threading

from projection_interfaces.srv import PrologFinish, PrologNextSolution, PrologQuery
import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from std_srvs.srv import Trigger

from projection_server import projection, world
from projection_server.service.spin import run_node
from projection_server.service import prolog_bridge
from projection_server.service.parameters import descriptor, PARAMETERS
from projection_server.service.project_action import ProjectActionServer
from projection_server.service.queries import (ALL, INCREMENTAL, ONCE, QueryError, QueryEvent,
                                       QueryManager, ServerLimits)
from projection_server.world.listener import WorldListener

__all__ = ['ProjectionServerNode', 'main']

_MODES = {PrologQuery.Request.ALL_SOLUTIONS: ALL,
          PrologQuery.Request.INCREMENTAL: INCREMENTAL,
          PrologQuery.Request.ONCE: ONCE}

_STATUS = {'solution': PrologNextSolution.Response.OK,
           'none': PrologNextSolution.Response.NO_SOLUTION,
           'wrong_id': PrologNextSolution.Response.WRONG_ID,
           'error': PrologNextSolution.Response.QUERY_FAILED}

# Query text in INFO logs is cut to this many characters.
LOG_TEXT_PREFIX = 80


def _last_resort(callback):
    """Turn any exception of a service callback into a ``system_error`` response."""
    @functools.wraps(callback)
    def guarded(self, request, response):
        try:
            return callback(self, request, response)
        except Exception as exc:  # noqa: BLE001 - the node must keep serving
            self.get_logger().error(f'{callback.__name__} failed: {type(exc).__name__}: {exc}')
            message = f'internal error: {type(exc).__name__}: {exc}'
            for name, value in (('ok', False), ('error_kind', 'system_error'),
                                ('message', message),
                                ('status', PrologNextSolution.Response.QUERY_FAILED)):
                if hasattr(response, name):
                    try:
                        setattr(response, name, value)
                    except (TypeError, ValueError, AssertionError):
                        pass
            return response
    return guarded


@functools.cache
def _libc():
    return ctypes.CDLL(ctypes.util.find_library('c'))


def _malloc_trim() -> None:
    try:
        _libc().malloc_trim(0)
    except (AttributeError, OSError):   # not glibc
        pass


class _RosLogHandler(logging.Handler):
    """Forwards the package's Python log records (e.g. the worker pool's) to rclpy."""

    def __init__(self, logger):
        super().__init__()
        self._logger = logger

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
            if record.levelno >= logging.ERROR:
                self._logger.error(text)
            elif record.levelno >= logging.WARNING:
                self._logger.warning(text)
            elif record.levelno >= logging.INFO:
                self._logger.info(text)
            else:
                self._logger.debug(text)
        except Exception:  # noqa: BLE001 - logging must not raise
            pass


class ProjectionServerNode(Node):
    """Answers Prolog queries sent as service requests."""

    def __init__(self, **kwargs):
        super().__init__('projection_server', **kwargs)
        for spec in PARAMETERS:
            if spec.default == []:
                self._declare_string_array(spec.name, descriptor(spec))
            else:
                self.declare_parameter(spec.name, spec.default, descriptor(spec))
        self.add_on_set_parameters_callback(self._check_parameters)

        bag_dir = self.get_parameter('bag_dir').value or None
        _check_bag_dir(Path(bag_dir).expanduser() if bag_dir else projection.default_bag_dir())
        self._log_handler = _RosLogHandler(self.get_logger())
        logging.getLogger('projection_server').addHandler(self._log_handler)
        # Python's and rclpy's severities share their numbers (DEBUG 10 ... FATAL 50), so the
        # package's records follow the node's --log-level.
        logging.getLogger('projection_server').setLevel(
            int(self.get_logger().get_effective_level()) or logging.INFO)
        projection.configure(
            bag_dir=bag_dir,
            workers=int(self.get_parameter('projection_workers').value),
            retention={'max_bags': int(self.get_parameter('max_bags').value)},
            backend=self.get_parameter('projection_backend').value,
            ray_address=self.get_parameter('ray_address').value,
            engine=self.get_parameter('physics_engine').value)
        projection.start()
        prolog_bridge.load(options={name: self._string_array(name)
                                    for name in ('kb_files', 'asset_paths')})
        self.world_listener = None
        if self.get_parameter('robot_world').value:
            self.world_listener = WorldListener(self)
            world.set_current(self.world_listener.world)
        self.queries = QueryManager(self._limits(), on_event=self._log_query)

        group = ReentrantCallbackGroup()
        self.create_service(PrologQuery, '~/query', self._on_query, callback_group=group)
        self.create_service(PrologNextSolution, '~/next_solution', self._on_next,
                            callback_group=group)
        self.create_service(PrologFinish, '~/finish', self._on_finish, callback_group=group)
        self.create_service(Trigger, '~/ping', self._on_ping, callback_group=group)
        self.project_action = ProjectActionServer(self, self.queries, callback_group=group)
        self._queries_since_trim = False
        self.create_timer(1.0, self._housekeeping,
                          callback_group=MutuallyExclusiveCallbackGroup())
        self.get_logger().info(
            f'answering Prolog queries on {self.get_fully_qualified_name()}/query '
            f'(max_engines={self.queries.limits.max_engines})')

    def _string_array(self, name: str) -> list[str]:
        return list(self.get_parameter(name).value)

    def _limits(self, overrides: dict | None = None) -> ServerLimits:
        value = {p: self.get_parameter(p).value for p in
                 ('max_engines', 'default_timeout', 'max_solutions', 'idle_timeout', 'sandbox')}
        value.update(overrides or {})
        return ServerLimits(max_engines=int(value['max_engines']),
                            default_timeout=float(value['default_timeout']),
                            max_solutions=int(value['max_solutions']),
                            idle_timeout=float(value['idle_timeout']),
                            sandbox=bool(value['sandbox']))

    def _declare_string_array(self, name: str, descriptor: ParameterDescriptor) -> None:
        """Declare string array ``name`` with the empty list as its default.

        rclpy types an empty list as a byte array, and a parameter file's ``[]`` (what
        ``ros2 param dump`` writes) as no value; a parameter without a value makes rclpy's
        get_parameters service answer nothing at all to a request that names it, so ``ros2
        param dump`` would print no parameter. The empty list is given its type here.
        """
        value = self.declare_parameter(name, Parameter.Type.STRING_ARRAY, descriptor)
        if value.type_ == Parameter.Type.NOT_SET:
            # Read-only, so set_parameters would refuse it; rclpy has no public way.
            self._parameters[name] = Parameter(name, Parameter.Type.STRING_ARRAY, [])

    def _check_parameters(self, params) -> SetParametersResult:
        changes = {}
        for p in params:
            if p.name in ('default_timeout', 'idle_timeout') and not float(p.value) > 0:
                return SetParametersResult(successful=False, reason=f'{p.name} must be > 0')
            if p.name == 'max_solutions' and int(p.value) < 1:
                return SetParametersResult(successful=False, reason='max_solutions must be >= 1')
            changes[p.name] = p.value
        if hasattr(self, 'queries'):
            self.queries.limits = self._limits(changes)
        return SetParametersResult(successful=True)

    def _housekeeping(self) -> None:
        """Reap idle queries; when no engine is busy after queries ran, hand the memory
        their engines freed back to the system."""
        self.queries.reap()
        if self._queries_since_trim and self.queries.stats()['engines'] == 0:
            self._queries_since_trim = False
            # glibc keeps freed memory in per-thread arenas; without this, a burst of
            # queries from many threads would leave the node's RSS at its peak.
            _malloc_trim()

    def _log_query(self, e: QueryEvent) -> None:
        """Errors at INFO, successes at DEBUG; the query text only as a bounded prefix."""
        self._queries_since_trim = True
        text = e.text if len(e.text) <= LOG_TEXT_PREFIX else e.text[:LOG_TEXT_PREFIX] + '...'
        what = (f'query {e.id!r} ({e.mode}) {e.event} after {e.duration:.3f} s: '
                + (f'error {e.kind}' if e.kind else f'{e.solutions} solution(s)'))
        logger = self.get_logger()
        if e.event == 'abandoned':
            logger.warning(f'{what}; its engine is being interrupted: {text!r}')
        elif e.kind or e.event == 'reaped':
            logger.info(f'{what}: {text!r}')
        else:
            logger.debug(f'{what}: {text!r}')

    # -- service callbacks: request -> plain call -> response ------------------------
    @_last_resort
    def _on_query(self, request, response):
        mode = _MODES.get(request.mode)
        answer = self.queries.query(mode or f'mode {request.mode}', request.id, request.query,
                                    request.timeout, request.max_solutions)
        response.ok = answer.ok
        response.message = answer.message
        response.id = answer.id
        response.error_kind = answer.kind
        response.error = answer.error
        response.solutions = answer.solutions
        response.truncated = answer.truncated
        return response

    @_last_resort
    def _on_next(self, request, response):
        outcome = self.queries.next_solution(request.id)
        response.status = _STATUS.get(outcome.status, PrologNextSolution.Response.QUERY_FAILED)
        response.solution = outcome.bindings
        response.error_kind = outcome.kind
        response.message = outcome.message
        return response

    @_last_resort
    def _on_finish(self, request, response):
        try:
            self.queries.check_id(request.id)
            response.closed = self.queries.finish(request.id)
            response.ok = True
            n = response.closed
            response.message = f'closed {n} quer{"y" if n == 1 else "ies"}'
        except QueryError as exc:
            response.ok = False
            response.message = exc.message
        return response

    @_last_resort
    def _on_ping(self, request, response):
        response.success = True
        response.message = json.dumps({**self.queries.stats(), **_process_stats()})
        return response

    def destroy_node(self):
        if hasattr(self, 'project_action'):
            self.project_action.destroy()
        if hasattr(self, 'queries'):
            self.queries.shutdown()
        if getattr(self, 'world_listener', None) is not None:
            world.set_current(None)
            self.world_listener.destroy()
        if hasattr(self, '_log_handler'):
            logging.getLogger('projection_server').removeHandler(self._log_handler)
        projection.shutdown()
        super().destroy_node()


def _process_stats() -> dict[str, int]:
    """The node process's id, threads and resident memory (for monitoring and leak tests)."""
    stats = {'pid': os.getpid(), 'threads': threading.active_count()}
    try:
        with open('/proc/self/statm', encoding='ascii') as f:
            stats['rss_kib'] = int(f.read().split()[1]) * os.sysconf('SC_PAGE_SIZE') // 1024
    except (OSError, ValueError, IndexError):
        pass
    return stats


def _check_bag_dir(path: Path) -> None:
    """Refuse to start with a bag directory that cannot be one."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise StartupError(f'bag_dir {str(path)!r} is not a usable directory: '
                           f'{exc.strerror or exc}') from exc
    if not path.is_dir():
        raise StartupError(f'bag_dir {str(path)!r} is not a directory')


class StartupError(Exception):
    """The node cannot start with its parameters."""


def main(args=None) -> int:
    # One executor thread per engine, plus spares so that finish/next/ping requests are
    # served while every engine is busy.
    return run_node('projection_server', ProjectionServerNode,
                    lambda node: node.queries.limits.max_engines + 4,
                    (prolog_bridge.BridgeError, StartupError, projection.ProjectionError), args)


if __name__ == '__main__':
    sys.exit(main())
