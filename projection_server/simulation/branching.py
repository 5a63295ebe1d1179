"""Projections that part only after their set-up: the steps they share once, then a fork.

Parametrizations of a program with ``setup_params`` that agree in them (pours from one
position at several angles and times, grasps at several forces) step alike until their
commands first differ. :func:`run_tree` runs them as a tree of processes: a process steps
while the commands of all its parametrizations agree, then forks a child for each group
whose commands for the next step agree, and each child goes on with its group's
parameters (the task's ``retarget``). A child's PyBullet world is its parent's memory, so
it continues exactly, which ``restoreState`` does not: every leaf's bag is, byte for byte,
the bag of a straight :meth:`~projection_server.simulation.runner.Simulator.run` (tests
compare them). A MuJoCo world is all in the process's objects (``Engine.copyable``):
there a group goes on in a deep copy of the projection, in the same process, which costs
a few milliseconds where a fork and the pages its child copies cost tens.

The monitor's messages of the shared steps are kept, not written. Each leaf writes a bag of
its own: its own ``/projection/info`` first, then the kept messages in the order they were
made, then those of its own steps.

A parent waits for each child before it forks the next, so a tree uses one core, like one
projection at a time. Every child dies with its parent (``PR_SET_PDEATHSIG``): stopping the
process that called :func:`run_tree` stops its whole tree.

Where the worlds copy, no process need be forked at all: :func:`run_in_process` runs the
whole tree in the calling process, reporting each leaf there. A forked root costs the pages
its child copies and, after it, the faults of the worker's own first writes to them; in the
process, a tree costs only its copies (bench/RESULTS.md).
"""

from __future__ import annotations

import copy
import gc
import math
import os
import time
import traceback
from typing import Any, Callable, TYPE_CHECKING

from projection_server.bags import BagWriter, Record, TOPICS, typestore
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.lifetime import die_with_parent
from projection_server.simulation import engines
from projection_server.simulation.runner import collector_paused, Projection, projection_info

if TYPE_CHECKING:
    from collections.abc import Sequence
    from pathlib import Path

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings

__all__ = ['Report', 'run_in_process', 'run_tree', 'start_tree']

# report(index, the finished Projection or a ProjectionError, ok): once per leaf, from the
# leaf's process (which makes the timeline of a finished one, its records in memory).
Report = Callable[[int, Any, bool], None]


def run_tree(simulator: Any, leaves: Sequence[tuple[Job, Path]], settings: Settings,
             report: Report) -> bool:
    """Run the projections ``leaves`` (a job and the path of its new bag each; all of one
    program, scenario, physics and set-up parameters) as a tree of processes below the
    calling one, in a world of ``simulator``'s, and ``report`` each.

    Returns whether every process of the tree ended normally; if not (one crashed), the
    leaves it had not reported yet are not reported.
    """
    return os.waitpid(start_tree(simulator, leaves, settings, report), 0)[1] == 0


def start_tree(simulator: Any, leaves: Sequence[tuple[Job, Path]], settings: Settings,
               report: Report) -> int:
    """:func:`run_tree` without waiting: the pid of the tree's root, which leads a process
    group of the whole tree (to be paused and continued with ``os.killpg``); wait for it
    with ``os.waitpid``."""
    return _fork(lambda: _root(simulator, list(enumerate(leaves)), settings, report), True)


def run_in_process(simulator: Any, leaves: Sequence[tuple[Job, Path]], settings: Settings,
                   report: Report) -> bool:
    """:func:`run_tree` in the calling process, for an engine whose worlds copy
    (``Engine.copyable``): each group goes on in a copy of the world, and ``report`` is
    called here, after each leaf (what it does waits for the next leaf). Returns True:
    every leaf is reported, a failure as a :class:`ProjectionError`.

    Without the cyclic garbage collector, as :meth:`Simulator.run`: what the finished leaves
    leave in cycles is small (0.3 MB for 11 grasps, 2.7 MB for 64), and is collected after
    the tree; a young collection after each leaf cost 2.3 ms of its 60."""
    with collector_paused():
        return _root(simulator, list(enumerate(leaves)), settings, report) == 0


class _SharedLog:
    """Writes like a :class:`~projection_server.bags.BagWriter`, but only keeps the calls,
    to be made again into each leaf's bag."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self._types = typestore().types

    def new(self, msgtype: str, **fields: Any) -> Any:
        return self._types[msgtype](**fields)

    def write(self, topic: str, message: Any, t_ns: int) -> None:
        self.calls.append(('write', (topic, message, t_ns)))

    def write_sample(self, t_ns: int, messages: Any) -> None:
        self.calls.append(('write_sample', (t_ns, list(messages))))

    def write_samples(self, samples: Any) -> None:
        self.calls.append(('write_samples', (list(samples),)))


def _root(simulator: Any, group: list[tuple[int, tuple[Job, Path]]], settings: Settings,
          report: Report) -> int:
    try:
        cpu = time.process_time()   # 0 in a forked root; the tree's start in the process
        log = _SharedLog()
        projection = Projection(simulator, group[0][1][0], settings, log)
        projection.cpu_from = cpu
    except Exception as exc:
        return _fail(group, exc, report)
    return _grow(projection, log, group, settings, report)


def _grow(projection: Projection, log: _SharedLog, group: list[tuple[int, tuple[Job, Path]]],
          settings: Settings, report: Report) -> int:
    """Step ``group``'s shared steps, then fork its subgroups (or end its one leaf); the
    exit code of the process: 0 unless a child ended abnormally."""
    physics, task = projection.physics, projection.task
    try:
        task.retarget(dict(group[0][1][0].params))
        if len(group) == 1:
            _leaf(projection, log, group[0], settings, report)
            return 0
        params = [dict(job.params) for _, (job, _) in group]
        end = math.ceil(task.duration * physics.settings.physics.rate_hz - 1e-9)
        # Step by step while every parametrization would command the same next: what a
        # task commands may depend on the world (a plan's next step starts when the one
        # under way has ended), so it is asked of the world as it is, step by step.
        step = physics.step_count
        while step < end and len({task.command_at(p, step) for p in params}) == 1:
            projection.advance(step + 1)
            step += 1
        subgroups: dict[Any, list[tuple[int, tuple[Job, Path]]]] = {}
        for member, p in zip(group, params):
            # Commands that never part (to the first one's end): each its own leaf.
            key = task.command_at(p, step) if step < end else member[0]
            subgroups.setdefault(key, []).append(member)
    except Exception as exc:
        return _fail(group, exc, report)
    code = 0
    if engines.get(physics.engine).copyable:   # the world copies: no process to fork
        parts = list(subgroups.values())
        for subgroup in parts[:-1]:
            try:
                copied = _copied(projection, log)
            except Exception as exc:
                code |= _fail(subgroup, exc, report)
                continue
            code |= _grow(*copied, subgroup, settings, report)
        projection.cpu_from = time.process_time()   # what it shared is its parent's
        return code | _grow(projection, log, parts[-1], settings, report)
    for subgroup in subgroups.values():
        if _forked(lambda: _grow(projection, log, subgroup, settings, report)) != 0:
            code = 1
    return code


def _copied(projection: Projection, log: _SharedLog) -> tuple[Projection, _SharedLog]:
    """A copy of ``projection`` as it is now, logging into a copy of ``log``: for an
    engine whose world copies with it (``Engine.copyable``)."""
    # What no step changes is shared, not copied: the scenario, the settings, the records
    # and messages made so far (each is new when made, then left as it is).
    cpu = time.process_time()
    physics = projection.physics
    keep = [projection.scenario, physics.scenario, physics.settings, log,
            *projection.monitor.records]
    copied = copy.deepcopy(projection, {id(x): x for x in keep})
    copied.physics.after_copy()
    copied.cpu_from = cpu
    own = _SharedLog()
    own.calls = list(log.calls)
    copied.monitor.bag = own
    return copied, own


def _leaf(projection: Projection, log: _SharedLog, member: tuple[int, tuple[Job, Path]],
          settings: Settings, report: Report) -> None:
    index, (job, path) = member
    monitor = projection.monitor
    shared = log.calls
    with BagWriter(path) as bag:
        info = bag.new(shared[0][1][1].__msgtype__, header=shared[0][1][1].header,
                       **projection_info(job, settings, projection.scenario.name))
        bag.write(TOPICS['info'], info, 0)
        for method, args in shared[1:]:
            getattr(bag, method)(*args)
        monitor.bag = bag
        monitor.records[0] = Record('info', 0, info)
        projection.advance()
    report(index, projection, True)


def _fail(group: list[tuple[int, tuple[Job, Path]]], exc: Exception, report: Report) -> int:
    if not isinstance(exc, ProjectionError):
        exc = ProjectionError(ErrorKind.SIMULATION_FAILED, f'{type(exc).__name__}: {exc}\n'
                                                   f'{traceback.format_exc(limit=8)}')
    for index, _ in group:
        report(index, exc, False)
    return 0


def _forked(work: Callable[[], int]) -> int:
    """Run ``work`` in a forked child, which dies with this process and exits with what
    ``work`` returns (1 if it raised); the child's wait status, once it has ended."""
    return os.waitpid(_fork(work), 0)[1]


def _fork(work: Callable[[], int], group: bool = False) -> int:
    """:func:`_forked` without waiting: the child's pid (with ``group``, the leader of a
    new process group)."""
    parent = os.getpid()
    # A child's garbage collections would touch every object it shares with its parent,
    # which copies their pages: tens of ms a child, a grasp's approach. Frozen, the
    # parent's objects are left out of them (and, here, given back to the collector).
    gc.freeze()
    pid = os.fork()
    if pid != 0:
        gc.unfreeze()
    if pid == 0:
        code = 1
        try:
            if group:
                os.setpgid(0, 0)
            if die_with_parent(parent):
                code = work()
        finally:
            os._exit(code)
    if group:
        # Here too, so that the group exists when this returns: the caller may signal it
        # (os.killpg) before the child has run at all.
        try:
            os.setpgid(pid, pid)
        except ProcessLookupError:   # the child has ended already
            pass
    return pid
