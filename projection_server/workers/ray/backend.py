"""The ``ray`` backend: one Ray actor per worker, each with a warm simulator.

For when one machine is not enough: the actors (:mod:`.actor`) may run on any node of a Ray
cluster. One dispatcher thread hands each idle actor one job at a time, or, as the ``local``
backend does, the queued jobs of one family up to a fair share per actor, run as a tree
(:mod:`projection_server.simulation.branching`) whose projections come back one by one as
they end. The dispatcher sleeps until a result, a new job or a time limit wakes it: each
call's future, and a thread per tree that follows its results, put what ends on a queue
that it waits on. A job's time limit counts from when its actor takes it, in a tree from
when the one before it ended. As in the ``local`` backend, queued jobs are taken by owner
(query) in turn, and while every actor is busy, an actor running a tree pauses it for
another query's projection. Finished bags come back as bytes and are published into this
process's :class:`~projection_server.workers.bag_store.BagStore` under the same job key as
the local backend uses, so either backend answers from the bags of the other.

Failures, chosen so that a projection that failed is reported, never silently run again:

* actors are created with ``max_restarts=-1``: a dead actor process (a crash, a kill, a
  timeout or a cancel, which stop a running projection by killing its actor) is restarted
  by Ray, warm again, for the next job;
* projections are sent with ``max_task_retries=0``: the one that was running fails with kind
  ``worker_crashed`` (or ``timeout``, ``cancelled``), never silently re-run; the readiness
  call after a restart is the one call that waits through the restart;
* a tree whose actor dies or runs over time is not failed as a whole, since it is not known
  which of its projections did it: those it had not finished run again one by one, each
  with its own time limit (and so its own error), as in the ``local`` backend. A tree is
  stopped by a cancel once none of its unfinished projections is wanted.

PyBullet keeps a little memory per world it has built, so, as in the local backend, an
actor is replaced by a fresh one after ``max_projections`` projections, while no job waits
for it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import logging
import os
from pathlib import Path
import queue
import shutil
import threading
import time
from typing import Any, TYPE_CHECKING

import ray
from ray.exceptions import RayActorError, RayError

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.job import code_version
from projection_server.workers.backend import ProjectionResult
from projection_server.workers.base import BackendBase
from projection_server.workers.messages import LeafResult, TreeEnded
from projection_server.workers.ray.actor import ProjectionActor

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings
    from projection_server.workers.bag_store import Retention
    from projection_server.workers.requests import Request

__all__ = ['RayBackend', 'connect']

_log = logging.getLogger(__name__)  # the node forwards it to /rosout

LOCAL_OBJECT_STORE = 100 * 1024 ** 2   # bytes: bags pass through it, a few MB each


@dataclass
class _Actor:
    """One actor and what it does now: starting (``ref`` is its readiness call), idle,
    running ``request`` (``ref`` is the projection) or a tree of the requests ``tree`` (by
    index; ``ref`` is its generator; those it has finished are removed) until
    ``deadline``; and, while its tree waits, another query's projection ``other`` (its
    call ``other_ref``) until ``other_deadline``."""

    handle: Any
    ref: Any = None
    request: Request | None = None
    tree: dict[int, Request] | None = None
    other: Request | None = None
    other_ref: Any = None
    other_deadline: float = 0.0
    started: float = 0.0
    deadline: float = 0.0
    timed_out: bool = False
    projections: int = 0
    info: dict[str, Any] | None = None
    error: ProjectionError | None = None

    @property
    def idle(self) -> bool:
        return self.ref is None and self.other is None


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
        # What wakes the dispatcher: (a call or a tree's generator, its outcome) when one
        # ends or a tree's projection does; None when there may be new work.
        self._events: queue.SimpleQueue[tuple[Any, Any] | None] = queue.SimpleQueue()
        self._queue: deque[Request] = deque()
        self._actors = [self._new_actor() for _ in range(workers)]
        self._thread = threading.Thread(target=self._dispatch, name='ray-projection-dispatch',
                                        daemon=True)
        self._thread.start()

    @property
    def workers(self) -> int:
        return len(self._actors)

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
                raise ProjectionError(ErrorKind.TIMEOUT, f'Ray actors not ready within {timeout:g} s')
            time.sleep(0.05)

    def _enqueue(self, request: Request) -> None:
        self._queue.append(request)
        self._events.put(None)

    def run(self, job: Job, timeout: float) -> str:
        """Run ``job`` (or find its bag) and return the bag's path."""
        return self.submit(job, timeout).result().bag

    def _droppable(self, request: Request) -> bool:
        # A tree makes its projections one after the other: those it has not made yet are
        # dropped like queued ones (see _stop).
        return request in self._queue or any(
            a.tree is not None and len(a.tree) > 1 and request in a.tree.values()
            for a in self._actors)

    def _stop(self, request: Request) -> bool:
        for actor in self._actors:
            if actor.other is request:
                return True   # killing it would kill the tree it pauses: it finishes
            if actor.request is request:
                _kill(actor.handle, restart=True)   # Ray restarts it
                return True
            if actor.tree is not None and request in actor.tree.values():
                # A tree stops once none of its unfinished projections is wanted any more.
                if all(r.cancelled for r in actor.tree.values() if not r.future.done()):
                    _kill(actor.handle, restart=True)
                return True
        if request in self._queue:
            self._queue.remove(request)
        return False

    def close(self) -> None:
        """Kill the actors; unfinished projections fail with kind ``pool_closed``."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._events.put(None)
            while self._queue:
                self._requests.fail(self._queue.popleft(), ProjectionError(
                    ErrorKind.POOL_CLOSED, 'the projection backend was closed'))
            for actor in self._actors:
                _kill(actor.handle, restart=False)
        self._thread.join(30.0)
        if self._stop_ray is not None:
            self._stop_ray()

    # -- the dispatcher thread ------------------------------------------------------------
    def _dispatch(self) -> None:
        try:
            while True:
                with self._lock:
                    if self._closed:
                        break
                    self._start_jobs()
                    self._start_others()
                    ends = self._ends()
                try:
                    events = [self._events.get(
                        timeout=max(0.0, min(ends) - time.monotonic()) if ends else None)]
                    while not self._events.empty():
                        events.append(self._events.get_nowait())
                except queue.Empty:
                    events = []
                for event in events:
                    if event is not None:
                        self._handle(*event)
                self._check_deadlines()
        finally:
            with self._lock:
                for actor in self._actors:
                    for request in _running(actor):
                        self._requests.fail(request, ProjectionError(
                            ErrorKind.POOL_CLOSED, 'the projection backend was closed'))

    def _ends(self) -> list[float]:
        """When :meth:`_check_deadlines` must look next (called with the lock)."""
        ends = []
        for actor in self._actors:
            if _running(actor):
                if not actor.timed_out:   # else killed: its end comes as an event
                    ends.append(_deadline(actor))
            elif actor.ref is not None and self._queue:   # starting, with jobs waiting
                ends.append(actor.started + self.startup_timeout)
        return ends

    def _handle(self, source: Any, outcome: Any) -> None:
        """What ended: ``source`` (a call, or a tree's generator) of one of the actors, if
        it is still theirs; ``outcome`` is the call's future, or the tree's message."""
        actor = next((a for a in self._actors if source is a.ref or source is a.other_ref),
                     None)
        if actor is None:
            return   # of an actor lost or replaced meanwhile
        if source is actor.other_ref:
            self._finish_other(actor, outcome)
        elif actor.tree is not None:
            self._tree_message(actor, outcome)
        else:
            self._finish(actor, outcome)

    def _watch(self, call: Any) -> Any:
        """Have ``call`` (an ObjectRef) wake the dispatcher when it ends; returns it."""
        call.future().add_done_callback(lambda future: self._events.put((call, future)))
        return call

    def _follow(self, generator: Any) -> Any:
        """Have each message of a tree's ``generator`` wake the dispatcher, from a thread
        that waits for them; returns it."""
        def follow() -> None:
            while True:
                try:
                    message = ray.get(next(generator))
                except StopIteration:   # ended without its last message
                    message = TreeEnded(False)
                except Exception as exc:   # noqa: BLE001 (the dispatcher says what it was)
                    message = exc
                self._events.put((generator, message))
                if not isinstance(message, LeafResult):
                    return

        threading.Thread(target=follow, name='ray-tree-results', daemon=True).start()
        return generator

    def _start_jobs(self) -> None:
        """Give queued requests to idle actors, by owner in turn, a family's together
        (called with the lock)."""
        self._queue = deque(r for r in self._queue if not r.future.done())
        started = False
        for actor in self._actors:
            if not self._queue:
                break
            if not actor.idle:
                continue
            request = self._next(list(self._queue), self._queue)
            if request is None:
                break
            if actor.error is not None:   # its start-up failed: this job says why, then retry
                self._requests.fail(request, actor.error)
                self._replace(actor)
                continue
            busy = sum(len(_running(a)) for a in self._actors)
            taken, self._queue = self._with_family(request, self._queue, busy)
            self._count(taken)
            started = True
            actor.started = time.monotonic()
            actor.timed_out = False
            if len(taken) == 1:
                actor.request = request
                actor.ref = self._watch(actor.handle.project.remote(
                    request.job, self.store.name(request.job, request.key)))
                actor.deadline = actor.started + request.timeout
            else:
                _log.debug('a tree of %d projections from %s', len(taken), request.key[:12])
                actor.tree = dict(enumerate(taken))
                actor.ref = self._follow(actor.handle.tree.options(
                    num_returns='streaming').remote(
                    [(r.job, self.store.name(r.job, r.key)) for r in taken]))
                actor.deadline = actor.started + max(r.timeout for r in taken)
        if started:
            self._forget_owners([*self._queue, *(r for a in self._actors for r in _running(a))])

    def _start_others(self) -> None:
        """While every actor is busy, have an actor whose tree runs pause it for another
        query's queued projection (called with the lock)."""
        if not self._queue or any(a.idle for a in self._actors):
            return
        for actor in self._actors:
            owners = _pausable(actor)
            if owners is None:
                continue
            request = self._next([r for r in self._queue if not r.owners & owners],
                                 self._queue)
            if request is None:
                continue
            self._count([request])
            actor.other = request
            actor.other_ref = self._watch(actor.handle.project.remote(
                request.job, self.store.name(request.job, request.key)))
            actor.other_deadline = time.monotonic() + request.timeout

    def _answer(self, actor: _Actor, future: Any) -> tuple[Any, bool] | None:
        """``(result, ok)`` of ``actor``'s ended call (its ``future``); None if the actor
        died (handled)."""
        try:
            return future.result()
        except RayActorError as exc:
            self._lost(actor, exc)
            return None
        except RayError as exc:
            return ProjectionError(ErrorKind.SIMULATION_FAILED, f'{type(exc).__name__}: {exc}'), False

    def _finish_other(self, actor: _Actor, future: Any) -> None:
        """The projection that paused ``actor``'s tree has ended."""
        request = actor.other
        answer = self._answer(actor, future)
        if answer is None:
            return
        result = self._result(request, *answer)
        with self._lock:
            if actor.other is not request:
                return   # lost meanwhile
            actor.other = actor.other_ref = None
            self._settle(actor, request, result)
            _tree_deadline(actor, self.startup_timeout)   # the pause does not count
            self._events.put(None)

    def _finish(self, actor: _Actor, future: Any) -> None:
        request = actor.request
        answer = self._answer(actor, future)
        if answer is None:
            return
        value, ok = answer
        if request is None:   # the actor's readiness call
            with self._lock:
                actor.ref = None
                if ok and value['code_version'] != self._code:
                    value, ok = ProjectionError(
                        ErrorKind.INVALID_SETTINGS,
                        f'a Ray worker on node {value["node"]} runs projection_server code '
                        f'{value["code_version"]}, this node {self._code}: install the '
                        'same version on every machine of the cluster'), False
                actor.info, actor.error = (value, None) if ok else (None, value)
            return
        result = self._result(request, value, ok)
        with self._lock:
            actor.ref = actor.request = None
            self._settle(actor, request, result)
            if actor.projections >= self.max_projections and not self._closed:
                self._replace(actor)
            self._events.put(None)

    def _tree_message(self, actor: _Actor, value: Any) -> None:
        """The next message of the tree that ``actor`` runs: a projection's result, or its
        end (after which the projections it did not finish are queued again, one by one),
        or the error that ended it."""
        if isinstance(value, RayActorError):
            self._lost(actor, value)
            return
        if isinstance(value, Exception):
            _log.warning('a tree of projections failed: %s', _first_line(value))
            value = TreeEnded(False)
        if isinstance(value, TreeEnded):
            with self._lock:
                left, actor.tree, actor.ref = list(actor.tree.values()), None, None
                self._again(left)
                if actor.projections >= self.max_projections and not self._closed:
                    self._replace(actor)
                self._events.put(None)
            return
        index = value.index
        request = actor.tree[index]
        result = self._result(request, value.result, value.ok)
        with self._lock:
            if actor.tree is None or actor.tree.pop(index, None) is not request:
                return   # the tree was lost meanwhile
            self._settle(actor, request, result)
            # Each projection of a tree has its limit from the end of the one before.
            _tree_deadline(actor, self.startup_timeout)

    def _result(self, request: Request, value: Any, ok: bool
                ) -> ProjectionResult | ProjectionError:
        try:
            return self._publish(request, value) if ok else value
        except Exception as exc:   # writing into the bag directory failed
            return ProjectionError(ErrorKind.BAG_ERROR, f'{type(exc).__name__}: {exc}')

    def _settle(self, actor: _Actor, request: Request,
                result: ProjectionResult | ProjectionError) -> None:
        """Give ``request`` its ``result`` (called with the lock)."""
        if isinstance(result, ProjectionResult):
            if not request.future.done():
                request.future.set_result(result)
        else:
            self._requests.fail(request, result)
        actor.projections += 1

    def _again(self, requests: list[Request]) -> None:
        """Queue a tree's unfinished ``requests`` again, first, each to run on its own
        (called with the lock); the cancelled ones fail."""
        if requests:
            _log.warning('%d projections of a tree run again one by one', len(requests))
        for request in reversed(requests):
            if request.future.done():
                continue
            if request.cancelled:
                self._requests.fail(request, ProjectionError(
                    ErrorKind.CANCELLED, f'projection {request.key[:12]} was cancelled'))
                continue
            request.family = None
            self._queue.appendleft(request)

    def _lost(self, actor: _Actor, exc: RayActorError) -> None:
        """The actor died: fail its projection (or queue its tree's unfinished ones again),
        wait for Ray to restart it."""
        with self._lock:
            request, tree, other = actor.request, actor.tree, actor.other
            actor.request = actor.tree = actor.other = actor.other_ref = None
            if other is not None:
                self._requests.fail(other, self._failure(
                    other, exc, time.monotonic() >= actor.other_deadline))
            if request is not None:
                self._requests.fail(request, self._failure(request, exc, actor.timed_out))
            if tree is not None:
                if self._closed:
                    for request in tree.values():
                        self._requests.fail(request, self._failure(request, exc, False))
                else:
                    self._again(list(tree.values()))
                    self._events.put(None)
            if self._closed:
                actor.ref = None
                return
            if request is None and tree is None and other is None:
                # Died for good while starting: the next job says so.
                actor.ref, actor.error = None, ProjectionError(
                    ErrorKind.WORKER_CRASHED, f'a Ray worker could not start: {_first_line(exc)}')
                return
            self._restarting(actor)

    def _failure(self, request: Request, exc: RayActorError, timed_out: bool
                 ) -> ProjectionError:
        """Why ``request`` failed when its actor died of ``exc``."""
        what = f'projection {request.key[:12]}'
        if self._closed:
            return ProjectionError(ErrorKind.POOL_CLOSED, f'the backend was closed during {what}')
        if request.cancelled:
            return ProjectionError(ErrorKind.CANCELLED, f'{what} was cancelled')
        if timed_out:
            return ProjectionError(ErrorKind.TIMEOUT, f'{what} took longer than {request.timeout:g} s')
        return ProjectionError(ErrorKind.WORKER_CRASHED,
                               f'Ray worker died during {what}: {_first_line(exc)}')

    def _check_deadlines(self) -> None:
        now = time.monotonic()
        with self._lock:
            for actor in self._actors:
                if actor.ref is None and actor.other is None:
                    continue
                if _running(actor):
                    if now >= _deadline(actor) and not actor.timed_out:
                        actor.timed_out = True
                        _kill(actor.handle, restart=True)
                elif now - actor.started > self.startup_timeout and self._queue:
                    # No actor could be placed or started (e.g. no free CPU in the cluster).
                    self._requests.fail(self._queue.popleft(), ProjectionError(
                        ErrorKind.TIMEOUT, f'no Ray worker started within {self.startup_timeout:g} s'
                        ' (are there free CPUs in the cluster?)'))
                    actor.started = now

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

    def _restarting(self, actor: _Actor) -> None:
        """Wait for Ray to restart the actor (called with the lock)."""
        actor.info, actor.projections = None, 0
        actor.ref = self._watch(actor.handle.ready.options(max_task_retries=-1).remote())
        actor.started = time.monotonic()

    def _new_actor(self) -> _Actor:
        actor = _Actor(self._remote.remote(self.settings.to_dict()))
        actor.ref = self._watch(actor.handle.ready.options(max_task_retries=-1).remote())
        actor.started = time.monotonic()
        return actor

    def _replace(self, actor: _Actor, kill: bool = True) -> None:
        """A new actor in place of one that cannot serve (called with the lock)."""
        if kill:
            _kill(actor.handle, restart=False)
        fresh = self._new_actor()
        actor.handle, actor.ref, actor.started = fresh.handle, fresh.ref, fresh.started
        actor.info = actor.error = actor.request = actor.tree = None
        actor.other = actor.other_ref = None
        actor.projections = 0


def _deadline(actor: _Actor) -> float:
    """The time limit of what ``actor`` runs: another query's projection's while it
    pauses the tree (the pause does not count against the tree)."""
    return actor.other_deadline if actor.other is not None else actor.deadline


def _tree_deadline(actor: _Actor, default: float) -> None:
    """Restart the time limit of ``actor``'s tree, if it runs one: the longest limit of
    the projections it has left (``default`` if none)."""
    if actor.tree is not None:
        actor.deadline = time.monotonic() + max(
            (r.timeout for r in actor.tree.values()), default=default)


def _pausable(actor: _Actor) -> set[str] | None:
    """The owners of the projections that ``actor``'s tree has not finished, if it could
    pause the tree for another query's projection; None if it runs none or runs one
    beside it already. A tree whose projections have all ended but whose end has not come
    yet has none to pause for: a projection started beside it would only keep the actor
    from its next tree (and split the next family into single projections)."""
    if not actor.tree or actor.other is not None:
        return None
    return {o for r in actor.tree.values() for o in r.owners}


def _running(actor: _Actor) -> list[Request]:
    """The requests that ``actor`` runs."""
    running = list(actor.tree.values()) if actor.tree is not None else (
        [actor.request] if actor.request is not None else [])
    return running + [actor.other] if actor.other is not None else running


def _kill(handle: Any, restart: bool) -> None:
    try:
        ray.kill(handle, no_restart=not restart)
    except (RayError, ValueError):   # already dead
        pass


def _first_line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__

