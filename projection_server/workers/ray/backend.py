"""The ``ray`` backend: one Ray actor per worker, each with a warm simulator.

For when one machine is not enough: the actors (:mod:`.actor`) may run on any node of a Ray
cluster. What each actor does next is decided by
:class:`~projection_server.workers.base.BackendBase`, as for the ``local`` backend (fair
turns by owner, a family's queued jobs up to a fair share per actor run as a tree, a tree
paused for another query's projection while no actor is idle, time limits, what a crash or
a cancel fails, replacement after ``max_projections``). This module carries it out with
Ray: a job is a ``project`` call; a tree (:mod:`projection_server.simulation.branching`) is
a ``tree`` call whose messages stream back as its projections end
(``num_returns='streaming'``); pausing a tree is a second ``project`` call beside it (the
actor has two threads); stopping an actor is ``ray.kill``. Finished bags come back as bytes
and are published into this process's
:class:`~projection_server.workers.bag_store.BagStore` under the same job key as the local
backend uses, so either backend answers from the bags of the other.

Calls are made at once by the thread that decides them, under the backend's lock: a
query's ``submit``, or the dispatcher after something ended. So a new job never waits for
the dispatcher to start. One dispatcher thread waits for what ends with ``ray.wait`` over
the outstanding calls and the trees' generators (Ray's documented way to wait for several
generators without a thread each), with a timeout up to the next time limit, and hands
each answer to the policy. ``ray.wait`` cannot be woken from outside, so while a
``submit`` could make a call the dispatcher is not waiting for (an actor is idle, failed or
starting, or a tree could be paused), it waits at most :data:`WATCH` s at a time: it then
waits for that call too before it can end (a projection takes longer), and its time limit
is kept to within that. With no call under way it sleeps on a condition that a new call
notifies.

Failures, chosen so that a projection that failed is reported, never silently run again:

* actors are created with ``max_restarts=-1``: a dead actor process (a crash, a kill, a
  timeout or a cancel, which stop a running projection by killing its actor) is restarted
  by Ray, warm again, for the next job;
* projections are sent with ``max_task_retries=0``: the one that was running fails with kind
  ``worker_crashed`` (or ``timeout``, ``cancelled``), never silently re-run; the readiness
  call after a restart is the one call that waits through the restart;
* a tree whose actor dies or runs over time is not failed as a whole, since it is not known
  which of its projections did it: those it had not finished run again one by one, each
  with its own time limit (and so its own error), as in the ``local`` backend.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import logging
import math
import os
from pathlib import Path
import shutil
import threading
import time
from typing import Any, ClassVar, TYPE_CHECKING

import ray
from ray.exceptions import RayActorError, RayError

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.job import code_version
from projection_server.workers.backend import ProjectionResult
from projection_server.workers.base import BackendBase, WorkerState
from projection_server.workers.messages import LeafResult, Ready, Result, TreeEnded
from projection_server.workers.ray.actor import ProjectionActor

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings
    from projection_server.workers.bag_store import Retention
    from projection_server.workers.base import Worker
    from projection_server.workers.requests import Request

__all__ = ['RayBackend', 'WATCH', 'connect']

_log = logging.getLogger(__name__)  # the node forwards it to /rosout

LOCAL_OBJECT_STORE = 100 * 1024 ** 2   # bytes: bags pass through it, a few MB each
# s: the longest wait while a submit could make a call the dispatcher does not wait for
WATCH = 0.1


@dataclass(eq=False)
class _Actor:
    """One actor and its calls under way: its readiness call (while it starts), its
    ``project`` calls by the request each runs (its job, or the one its tree is paused
    for), and its tree's message generator."""

    handle: Any
    ready_call: Any = None
    started: float = 0.0
    calls: dict[Any, Request] = field(default_factory=dict)
    stream: Any = None
    info: dict[str, Any] | None = None

    def waitables(self) -> list[Any]:
        """What the dispatcher waits for of this actor."""
        found = [self.ready_call] if self.ready_call is not None else []
        found.extend(self.calls)
        if self.stream is not None:
            found.append(self.stream)
        return found


def connect(address: str, workers: int) -> Callable[[], None] | None:
    """Join the Ray cluster at ``address`` (``auto``, ``ray://host:port`` or a head's
    ``host:port``), or start a local instance for ``workers`` actors when it is empty.

    Ray is started and stopped on a thread of its own that lives until then: Ray's local
    processes die with the thread that started them (``PR_SET_PDEATHSIG``), and a node
    starts its backend from whichever thread needs it first. Returns the function that
    stops Ray again, or None when this process was connected to Ray already.

    Raises:
        ProjectionError: kind ``pool_closed`` with Ray's reason when it cannot start or join.
    """
    if ray.is_initialized():
        return None
    options: dict[str, Any] = {'log_to_driver': False, 'configure_logging': False,
                               'namespace': 'projection_server'}
    if address:
        options['address'] = address
    else:
        options.update(num_cpus=workers, include_dashboard=False,
                       object_store_memory=LOCAL_OBJECT_STORE)
    started, stop = threading.Event(), threading.Event()
    failure: list[Exception] = []

    def own_ray() -> None:
        try:
            ray.init(**options)
        except Exception as exc:
            failure.append(exc)
            return
        finally:
            started.set()
        stop.wait()
        ray.shutdown()

    owner = threading.Thread(target=own_ray, name='ray-runtime', daemon=True)
    owner.start()
    started.wait()
    if failure:
        where = f'the Ray cluster at {address!r}' if address else 'a local Ray instance'
        exc = failure[0]
        raise ProjectionError(ErrorKind.POOL_CLOSED,
                              f'cannot start or join {where}: {type(exc).__name__}: {exc}'
                              ) from exc

    def shutdown() -> None:
        stop.set()
        owner.join(60.0)

    return shutdown


class RayBackend(BackendBase):
    """``workers`` Ray actors writing bags into ``bag_dir`` (a directory of this machine).

    ``address`` as for :func:`connect`. Implements
    :class:`~projection_server.workers.backend.WorkerBackend`; close it (or use it as a
    context manager) to kill its actors and, if it started Ray, to stop Ray.
    """

    _log: ClassVar[logging.Logger] = _log

    def __init__(self, bag_dir: str | os.PathLike[str], workers: int = 1,
                 settings: Settings | None = None,
                 retention: Retention | Mapping[str, Any] | None = None,
                 address: str = '', startup_timeout: float = 120.0,
                 max_projections: int = 200):
        super().__init__(bag_dir, workers, settings, retention, startup_timeout,
                         max_projections)
        self.address = address
        self._code = code_version()
        self._stop_ray = connect(address, workers)
        # One CPU per actor: Ray places actors where cores are free, spread over the nodes.
        # Two threads per actor: a tree, and another query's projection beside it.
        self._remote = ray.remote(ProjectionActor).options(
            num_cpus=1, max_restarts=-1, max_task_retries=0, scheduling_strategy='SPREAD',
            max_concurrency=2)
        self._called = threading.Condition(self._lock)   # a call was made, or closed
        self._actors = [_Actor(None) for _ in self._roster]
        with self._lock:
            for actor in self._actors:
                self._new_actor(actor)
        self._thread = threading.Thread(target=self._dispatch, name='ray-projection-dispatch',
                                        daemon=True)
        self._thread.start()

    def placement(self, timeout: float = 120.0) -> list[dict[str, Any]]:
        """Each actor's ``pid``, Ray ``node`` id and ``code_version``, once they are ready.

        Raises:
            ProjectionError: kind ``timeout`` if an actor is not ready within ``timeout`` s.
        """
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                infos = [actor.info for actor in self._actors]
            if all(info is not None for info in infos):
                return [dict(info) for info in infos]
            if time.monotonic() > deadline:
                raise ProjectionError(ErrorKind.TIMEOUT,
                                      f'Ray actors not ready within {timeout:g} s')
            time.sleep(0.05)

    def run(self, job: Job, timeout: float) -> str:
        """Run ``job`` (or find its bag) and return the bag's path."""
        return self.submit(job, timeout).result().bag

    def close(self) -> None:
        """Kill the actors; unfinished projections fail with kind ``pool_closed``."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            while self._queue:
                self._requests.fail(self._queue.popleft(), ProjectionError(
                    ErrorKind.POOL_CLOSED, 'the projection backend was closed'))
            for actor in self._actors:
                _kill(actor.handle, restart=False)
            self._called.notify_all()
        self._thread.join(30.0)
        if self._stop_ray is not None:
            self._stop_ray()

    # -- the transport (with the lock) ----------------------------------------------------
    def _send(self, worker: Worker) -> None:
        actor = self._actors[worker.index]
        if worker.state is WorkerState.RUNNING:
            self._project(actor, worker.request)
        else:
            leaves = [worker.leaves[i] for i in sorted(worker.leaves)]
            actor.stream = actor.handle.tree.options(num_returns='streaming').remote(
                [(r.job, self.store.name(r.job, r.key)) for r in leaves])
        self._called.notify()

    def _send_other(self, worker: Worker) -> None:
        self._project(self._actors[worker.index], worker.other)
        self._called.notify()

    def _project(self, actor: _Actor, request: Request) -> None:
        call = actor.handle.project.remote(request.job, self.store.name(request.job, request.key))
        actor.calls[call] = request

    def _halt(self, worker: Worker) -> None:
        _kill(self._actors[worker.index].handle, restart=True)   # Ray restarts it

    def _restart(self, worker: Worker) -> None:
        actor = self._actors[worker.index]
        _kill(actor.handle, restart=False)
        self._new_actor(actor)
        self._called.notify()

    def _new_actor(self, actor: _Actor) -> None:
        """A new actor process in ``actor``'s place (with the lock)."""
        actor.handle = self._remote.remote(self.settings.to_dict())
        actor.calls, actor.stream = {}, None
        self._restarting(actor)

    def _restarting(self, actor: _Actor) -> None:
        """Wait for the actor to be ready: Ray restarts it after a death (with the lock)."""
        actor.info = None
        actor.ready_call = actor.handle.ready.options(max_task_retries=-1).remote()
        actor.started = time.monotonic()

    # -- the dispatcher thread ------------------------------------------------------------
    def _dispatch(self) -> None:
        try:
            while True:
                with self._lock:
                    if self._closed:
                        break
                    now = time.monotonic()
                    for worker in self._roster:
                        self._overdue(worker, now)
                    self._late_start(now)
                    watched = {waitable: (actor, worker)
                               for actor, worker in zip(self._actors, self._roster)
                               for waitable in actor.waitables()}
                    until = self._until() - now
                    if not watched:   # a new call notifies
                        self._called.wait(None if until == math.inf else max(0.0, until))
                        continue
                    if self._may_call():
                        until = min(until, WATCH)
                ready, _ = ray.wait(list(watched), num_returns=1,
                                    timeout=None if until == math.inf else max(0.0, until))
                for waitable in ready:
                    self._handle(*watched[waitable], waitable)
        finally:
            with self._lock:
                self._fail_all(ProjectionError(ErrorKind.POOL_CLOSED,
                                               'the projection backend was closed'))

    def _until(self) -> float:
        """When the dispatcher must look again at the latest (with the lock)."""
        until = self._next_deadline()
        starting = [a.started + self.startup_timeout
                    for a, w in zip(self._actors, self._roster)
                    if w.state is WorkerState.STARTING and self._queue]
        return min([until, *starting])

    def _may_call(self) -> bool:
        """Whether a submit may make a call (or count a start-up's time limit) that the
        dispatcher does not wait for yet (with the lock)."""
        return any(w.state in (WorkerState.IDLE, WorkerState.FAILED, WorkerState.STARTING)
                   or w.pausable_owners() is not None for w in self._roster)

    def _late_start(self, now: float) -> None:
        """Fail a queued job for each actor that could not be placed or started in time
        (e.g. no free CPU in the cluster; with the lock)."""
        for actor, worker in zip(self._actors, self._roster):
            if (worker.state is WorkerState.STARTING and self._queue
                    and now - actor.started > self.startup_timeout):
                self._requests.fail(self._queue.popleft(), ProjectionError(
                    ErrorKind.TIMEOUT, f'no Ray worker started within {self.startup_timeout:g} s'
                    ' (are there free CPUs in the cluster?)'))
                actor.started = now

    def _handle(self, actor: _Actor, worker: Worker, waitable: Any) -> None:
        """What ended of ``actor``'s (``worker``'s): its readiness call, a ``project`` call,
        or the next message of its tree (ready: taking it does not block)."""
        if waitable is actor.stream:
            self._tree_message(actor, worker, waitable, lambda: ray.get(next(waitable)))
        elif waitable in actor.calls:
            self._call_ended(actor, worker, waitable, lambda: ray.get(waitable))
        elif actor.ready_call is not None and waitable == actor.ready_call:
            self._readiness(actor, worker, waitable, lambda: ray.get(waitable))

    def _readiness(self, actor: _Actor, worker: Worker, call: Any,
                   get: Callable[[], Ready]) -> None:
        """``actor``'s readiness ``call`` has ended (``get`` gives its answer)."""
        try:
            ready = get()
        except RayActorError as exc:   # died for good while starting: the next job says so
            error = ProjectionError(ErrorKind.WORKER_CRASHED,
                                    f'a Ray worker could not start: {_first_line(exc)}')
        except RayError as exc:
            error = ProjectionError(ErrorKind.SIMULATION_FAILED, f'{type(exc).__name__}: {exc}')
        else:
            error = None if ready.ok else ready.result
            if ready.ok and ready.result['code_version'] != self._code:
                error = ProjectionError(
                    ErrorKind.INVALID_SETTINGS,
                    f'a Ray worker on node {ready.result["node"]} runs projection_server code '
                    f'{ready.result["code_version"]}, this node {self._code}: install the '
                    'same version on every machine of the cluster')
        with self._lock:
            if actor.ready_call is None or call != actor.ready_call:
                return
            actor.ready_call = None
            if error is None:
                actor.info = ready.result
                self._started(worker)
            else:
                self._start_failed(worker, error)

    def _call_ended(self, actor: _Actor, worker: Worker, call: Any,
                    get: Callable[[], Result]) -> None:
        """A ``project`` call of ``actor`` has ended (``get`` gives its answer)."""
        with self._lock:
            request = actor.calls.get(call)
        if request is None:
            return
        try:
            answer = get()
        except RayActorError as exc:
            self._died(actor, worker, exc)
            return
        except RayError as exc:
            answer = Result(ProjectionError(ErrorKind.SIMULATION_FAILED,
                                            f'{type(exc).__name__}: {exc}'), False)
        result = self._result(request, answer)
        with self._lock:
            if actor.calls.pop(call, None) is None:
                return   # lost meanwhile
            self._answered(worker, request, result)
            self._stopped(actor, worker)

    def _tree_message(self, actor: _Actor, worker: Worker, stream: Any,
                      get: Callable[[], LeafResult | TreeEnded]) -> None:
        """The next message of the tree that ``actor`` runs (``get`` gives it): a
        projection's result, or its end, or the error that ended it."""
        try:
            message = get()
        except StopIteration:   # ended without its last message
            message = TreeEnded(False)
        except RayActorError as exc:
            self._died(actor, worker, exc)
            return
        except Exception as exc:   # noqa: BLE001 (its projections run again one by one)
            _log.warning('a tree of projections failed: %s', _first_line(exc))
            message = TreeEnded(False)
        if isinstance(message, LeafResult):
            with self._lock:
                request = worker.leaves.get(message.index)
            result = self._result(request, message) if request is not None else None
            with self._lock:
                if actor.stream is stream and result is not None:
                    self._leaf_answered(worker, message.index, result)
            return
        with self._lock:
            if actor.stream is not stream:
                return
            actor.stream = None
            self._tree_ended(worker)
            self._stopped(actor, worker)

    def _stopped(self, actor: _Actor, worker: Worker) -> None:
        """A stopped actor whose calls all ended before its death could show: it is
        restarted by Ray; wait for it (with the lock)."""
        if worker.state is WorkerState.STOPPING and not actor.calls and actor.stream is None:
            self._lost(worker, 'stopped')
            self._restarting(actor)

    def _died(self, actor: _Actor, worker: Worker, exc: RayActorError) -> None:
        """The actor died: the policy fails or queues again what it ran; wait for Ray to
        restart it."""
        with self._lock:
            actor.calls, actor.stream = {}, None
            self._lost(worker, f'Ray worker: {_first_line(exc)}')
            if not self._closed:
                self._restarting(actor)

    def _result(self, request: Request, answer: Result | LeafResult
                ) -> ProjectionResult | ProjectionError:
        """Publish the bag of ``answer``; or its error."""
        if not answer.ok:
            return answer.result
        try:
            return self._publish(request, answer.result)
        except Exception as exc:   # writing into the bag directory failed
            return ProjectionError(ErrorKind.BAG_ERROR, f'{type(exc).__name__}: {exc}')

    def _publish(self, request: Request, value: tuple[dict[str, bytes], dict[str, Any]]
                 ) -> ProjectionResult:
        """Write the bag's files into the bag directory and publish it."""
        files, timeline = value
        tmp = self.store.tmp_dir()
        try:
            bag = tmp / self.store.name(request.job, request.key)
            bag.mkdir()
            for name, data in files.items():
                (bag / Path(name).name).write_bytes(data)
            final = self.store.publish(bag)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        timeline['meta']['bag'] = str(final)
        return ProjectionResult(str(final), timeline)


def _kill(handle: Any, restart: bool) -> None:
    try:
        ray.kill(handle, no_restart=not restart)
    except (RayError, ValueError):   # already dead
        pass


def _first_line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
