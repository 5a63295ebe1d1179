"""The stand-in's simulator, in a process of its own: the one owner of its PyBullet world.

A robot publishes its state at its rate whatever it is doing. Building a world (loading
the URDF and its meshes, the egg's hull) holds Python's GIL for a tenth of a second at a
time, which would stall the node's publishing; so the simulation runs in a child process
(``spawn``: the node has threads and a Prolog engine, which a fork would copy), started once
and kept warm, and the node only reads its reports. The child answers each
:class:`Execution` with messages on its pipe::

    ('step', index, total, text)   # a step begins
    ('state', WorldState)          # at state_hz of simulated time
    ('done', Outcome, WorldState | None)   # the world after it (None: it did not start)

A cancel is an event the child checks with each state. The parent puts a time limit on
every wait, and replaces a child that died or did not answer.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import multiprocessing
import os
from pathlib import Path
import shutil
import signal
import tempfile
import time
from typing import Any, Callable, TYPE_CHECKING

from projection_server.errors import ProjectionError

if TYPE_CHECKING:
    from projection_server.standin.world import Observer, Outcome, StandinConfig, WorldState

__all__ = ['Execution', 'SimulationProcess']

# s of wall time an execution may take beyond its plan's bound (the plan program's own
# limit is 120 s of simulated time plus its settling).
WALL_LIMIT = 300.0
START_TIMEOUT = 60.0


@dataclass(frozen=True)
class Execution:
    """One plan to run: the scenario of the world now, the plan's steps (the plan program's
    form) and their texts, how the world runs, and the joints to report."""

    scenario: dict[str, Any]
    template: list[Any]
    texts: list[str]
    config: StandinConfig
    joints: list[str]


class SimulationProcess:
    """The warm child process that runs executions one at a time."""

    def __init__(self) -> None:
        self._context = multiprocessing.get_context('spawn')
        self._proc: Any = None
        self._conn: Any = None
        self._cancel: Any = None

    def start(self) -> None:
        """Start the child, if it is not running (its imports take a second or two)."""
        if self._proc is not None and self._proc.is_alive():
            return
        self.close()
        parent, child = self._context.Pipe()
        self._cancel = self._context.Event()
        self._proc = self._context.Process(target=_serve, args=(child, self._cancel, os.getpid()),
                                           name='standin_simulation', daemon=True)
        self._proc.start()
        child.close()
        self._conn = parent

    def run(self, execution: Execution, observer: Observer,
            on_state: Callable[[WorldState], None]) -> tuple[Outcome, WorldState | None]:
        """Run ``execution``; each state goes to ``on_state`` and the observer."""
        from projection_server.standin.world import Outcome
        self.start()
        self._cancel.clear()
        self._conn.send(execution)
        deadline = time.monotonic() + WALL_LIMIT + START_TIMEOUT
        while True:
            if observer.cancelled():
                self._cancel.set()
            late = time.monotonic() > deadline
            if late or not self._conn.poll(0.05):
                if late or not self._proc.is_alive():
                    what = (f'did not finish within {WALL_LIMIT + START_TIMEOUT:.0f} s' if late
                            else 'ended')
                    self.close()   # a new one is started for the next plan
                    return Outcome(False, f'the robot\'s simulation {what}'), None
                continue
            try:
                message = self._conn.recv()
            except EOFError:
                self.close()
                return Outcome(False, "the robot's simulation ended"), None
            kind = message[0]
            if kind == 'step':
                observer.step(*message[1:])
            elif kind == 'state':
                on_state(message[1])
                observer.state(message[1])
            else:
                return message[1], message[2]

    def close(self) -> None:
        """Stop the child: asked first, then terminated."""
        proc, conn, self._proc, self._conn = self._proc, self._conn, None, None
        if proc is None:
            return
        try:
            conn.send(None)
        except (OSError, ValueError):
            pass
        proc.join(timeout=5.0)
        if proc.is_alive():
            proc.terminate()
            proc.join(timeout=5.0)
        conn.close()


# --- the child ----------------------------------------------------------------------------

class _Cancelled(Exception):
    """The parent asked to stop."""


def _serve(conn: Any, cancel: Any, parent: int) -> None:
    from projection_server.lifetime import die_with_parent
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # the node stops it, after its own Ctrl-C
    if not die_with_parent(parent, signal.SIGKILL):
        return
    from projection_server.simulation.runner import Simulator
    simulator = None
    try:
        while True:
            try:
                execution = conn.recv()
            except EOFError:
                return
            if execution is None:
                return
            if simulator is None:
                simulator = Simulator()
            conn.send(('done', *_execute(simulator, execution, conn, cancel)))
    finally:
        if simulator is not None:
            simulator.close()


def _execute(simulator: Any, execution: Execution, conn: Any, cancel: Any
             ) -> tuple[Outcome, WorldState | None]:
    """Run the execution as a projection is run; its outcome and the world after it."""
    from projection_server.bags import BagWriter
    from projection_server.settings import load_settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Projection
    from projection_server.standin.world import event_text, Outcome
    from projection_server.timeline import translate_records

    started = time.monotonic()
    config = execution.config
    directory = Path(config.bag_dir) if config.bag_dir else Path(
        tempfile.mkdtemp(prefix='standin_'))
    try:
        settings = load_settings()
        base = settings.for_projection('plan').physics
        physics = {'rate_hz': base.rate_hz * config.physics_factor,
                   'solver_iterations': base.solver_iterations * config.physics_factor}
        job = Job.checked(execution.scenario, 'plan', {}, physics, plan=execution.template)
        directory.mkdir(parents=True, exist_ok=True)
        bag = directory / f'execution_{time.strftime("%Y%m%d_%H%M%S")}_{job.key(settings)[:8]}'
        error = ''
        with BagWriter(bag) as writer:
            projection = Projection(simulator.client, job, settings, writer)
            hook = _Hook(projection, execution, conn, cancel)
            projection.physics.step_hooks.append(hook)
            try:
                projection.advance()
            except _Cancelled:
                error = 'cancelled'
            except ProjectionError as exc:   # unreachable, too long: the robot stops there
                error = exc.message
        timeline = translate_records(projection.monitor.records, bag, projection.scenario)
        state = _read_state(projection, execution)
        broken = any(e[0] == 'break' and config.object_name in e[1]
                     for e in timeline['events'])
        plain = {k: timeline[k] for k in ('fluents', 'events', 'quantities')}
        return (Outcome(not error, error, [event_text(e) for e in timeline['events']], plain,
                        time.monotonic() - started, projection.physics.time),
                replace(state, broken=broken))
    except ProjectionError as exc:   # the plan or the world could not be set up
        return Outcome(False, exc.message, duration=time.monotonic() - started), None
    except Exception as exc:  # noqa: BLE001 - reported, and the robot keeps serving
        return Outcome(False, f'the robot\'s simulation failed: {type(exc).__name__}: {exc}',
                       duration=time.monotonic() - started), None
    finally:
        if not config.bag_dir:
            shutil.rmtree(directory, ignore_errors=True)


class _Hook:
    """After each physics step: a step's start, and at the state rate the state, paced to
    the wall clock."""

    def __init__(self, projection: Any, execution: Execution, conn: Any, cancel: Any):
        self.projection, self.execution, self.conn, self.cancel = (projection, execution,
                                                                   conn, cancel)
        rate = projection.physics.settings.physics.rate_hz
        self.every = max(1, round(rate / execution.config.state_hz))
        self.index = -1
        self.started = time.monotonic()   # after the world is built and has settled

    def __call__(self) -> None:
        physics, task = self.projection.physics, self.projection.task
        if task.index != self.index and 0 <= task.index < len(task.steps):
            self.index = task.index
            texts = self.execution.texts
            self.conn.send(('step', task.index + 1, len(task.steps),
                            texts[task.index] if task.index < len(texts) else ''))
        if physics.step_count % self.every:
            return
        self.conn.send(('state', _read_state(self.projection, self.execution)))
        if self.cancel.is_set():
            raise _Cancelled
        if self.execution.config.real_time:
            ahead = self.started + physics.time - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)


def _read_state(projection: Any, execution: Execution) -> WorldState:
    from projection_server.standin.world import WorldState
    physics, config = projection.physics, execution.config
    c = physics.client
    body = physics.body(config.robot_name).body_id
    indices = getattr(projection, '_standin_joints', None)
    if indices is None:
        names = {c.getJointInfo(body, j)[1].decode(): j for j in range(c.getNumJoints(body))}
        indices = projection._standin_joints = [names[n] for n in execution.joints]
    values = [s[0] for s in c.getJointStates(body, indices)]
    xyz, quaternion = physics.pose(config.object_name)
    return WorldState(dict(zip(execution.joints, map(float, values))),
                      tuple(map(float, xyz)), tuple(map(float, quaternion)), physics.time)
