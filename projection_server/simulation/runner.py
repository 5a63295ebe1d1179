"""One projection, start to end, in the calling process: world, program, monitoring, bag.

A :class:`Simulator` keeps a session of each engine it has run (a DIRECT-mode PyBullet
client, :mod:`~projection_server.simulation.engines`) for many projections (what a pool
worker does, :mod:`projection_server.workers.process`); each projection still builds a
fresh world in it and sets every engine parameter it depends on. A finished
:class:`Projection` keeps what its monitor logged (``monitor.records``), from which the
worker makes its timeline (:mod:`projection_server.workers.run`).
"""

from __future__ import annotations

import contextlib
import gc
import math
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.bags import BagWriter
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.canonical import canonical_json
from projection_server.settings import ENGINES
from projection_server.simulation import engines
from projection_server.simulation.job import code_version
from projection_server.simulation.monitor import Monitor
from projection_server.simulation.programs import get as get_program
from projection_server.simulation.scenario import parse_scenario

if TYPE_CHECKING:
    from collections.abc import Iterator
    from pathlib import Path

    from projection_server.simulation.job import Job
    from projection_server.settings import Settings

__all__ = ['Projection', 'Simulator', 'collector_paused', 'projection_info']


class Simulator:
    """Warm engine sessions (:mod:`~projection_server.simulation.engines`), one of each
    engine, that run projections one after the other."""

    def __init__(self) -> None:
        from projection_server.bags import typestore

        typestore()   # message types are registered once per process
        self._sessions: dict[str, Any] = {}
        for engine in ENGINES:   # opened (imported) before the first projection asks
            self.session(engine)

    @property
    def client(self) -> Any:
        """The PyBullet session's client."""
        return self.session('pybullet').client

    def session(self, engine: str) -> Any:
        """The open session of ``engine``."""
        session = self._sessions.get(engine)
        if session is None:
            session = self._sessions[engine] = engines.get(engine).open()
        return session

    def run(self, job: Job, settings: Settings, bag_path: Path) -> Projection:
        """Simulate ``job`` in a fresh world, log it into a new bag at ``bag_path`` and
        return the finished projection (its records are what the bag holds).

        The control program runs every ``steps_per_control`` physics steps and the monitor
        samples every ``steps_per_log`` steps, from the first step until the program's
        duration, or until the first sample after which the task says it has ``finished``
        (a task may end when what it set in motion has come to rest).
        """
        # A projection allocates a tuple or two per contact and step, nearly all freed by
        # their counts; the collections that allocation set off (13 young ones and every
        # tenth projection a full one of the worker's heap) cost 5-7 % of a MuJoCo grasp.
        with collector_paused():
            with BagWriter(bag_path) as bag:
                projection = Projection(self, job, settings, bag)
                projection.advance()
        return projection

    def close(self) -> None:
        for session in self._sessions.values():
            session.close()
        self._sessions = {}


class Projection:
    """One projection under way: ``job``'s fresh world in a session of its engine (of
    ``simulator``), its task and its monitor logging into ``bag`` (a
    :class:`~projection_server.bags.BagWriter`, or what writes like one), at step 0 with the
    ``/projection/info`` written.

    ``cpu_from``: the process's CPU time (``time.process_time``) when this projection's own
    steps began: 0 unless set (a tree's root sets its start; a process forked from the
    root's starts its clock at 0), a copy's when it was copied
    (:mod:`~projection_server.simulation.branching`)."""

    cpu_from = 0.0

    def __init__(self, simulator: Simulator | Any, job: Job, settings: Settings, bag: Any):
        """``simulator``: a :class:`Simulator`, or a PyBullet client of the caller's (the
        projection runs on PyBullet in it)."""
        if not hasattr(simulator, 'session'):
            simulator = _ClientSessions(simulator)
        self.scenario = scenario = parse_scenario(job.scenario)
        info = projection_info(job, settings, scenario.name)
        program = get_program(job.program)
        own = job.settings(settings)
        engines.check(own.physics.engine, job.program, scenario)
        self.physics = physics = simulator.session(own.physics.engine).build_world(
            scenario, own, tool_control=program.takes_plan)
        extra = {'plan': job.plan} if program.takes_plan else {}
        self.task = program.create(physics, scenario, dict(job.params),
                                   np.random.default_rng(int(info['job_key'][:16], 16)),
                                   **extra)
        self.monitor = Monitor(physics, bag, self.task)
        self.monitor.start(info)

    def advance(self, until: int | None = None) -> None:
        """Step on to step ``until``; None: to the program's end, its duration or the
        first sample after which the task has ``finished``, and write what the monitor
        still holds (also when a step raises)."""
        physics, task, monitor = self.physics, self.task, self.monitor
        control = physics.settings.control.steps_per_control
        log = physics.settings.control.steps_per_log
        finished = None
        to_end = until is None
        if to_end:
            until = math.ceil(task.duration * physics.settings.physics.rate_hz - 1e-9)
            finished = getattr(task, 'finished', None)
        step = physics.step
        try:
            while physics.step_count < until:
                if physics.step_count % control == 0:
                    task.control(physics)
                step()
                if physics.step_count % log == 0:
                    monitor.sample()
                    if finished is not None and finished(physics):
                        break
        finally:
            if to_end:   # the samples the monitor holds go into the bag before it closes
                monitor.flush()


@contextlib.contextmanager
def collector_paused() -> Iterator[None]:
    """Without the cyclic garbage collector inside: for work that allocates many objects
    that their reference counts free (a projection, a timeline), whose collections would
    traverse the same live objects again and again. What it leaves in cycles is collected
    after it."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if collecting:
            gc.enable()


class _ClientSessions:
    """The sessions of a caller's PyBullet client: PyBullet's only."""

    def __init__(self, client: Any):
        from projection_server.simulation.engines.pybullet import BulletSession

        self._session = BulletSession(client)

    def session(self, engine: str) -> Any:
        if engine != self._session.engine:
            raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                                  f'a PyBullet client cannot run the {engine} engine')
        return self._session


def projection_info(job: Job, settings: Settings, scenario_name: str) -> dict[str, str]:
    """The fields of the ``/projection/info`` message of ``job`` at ``settings`` (the
    global ones: the job's own are recorded)."""
    return {'job_key': job.key(settings), 'scenario_name': scenario_name,
            'scenario_json': canonical_json(job.scenario), 'program': job.program,
            'parameters_json': canonical_json(job.params),
            'settings_json': canonical_json(job.settings(settings).to_dict()),
            'code_version': code_version()}
