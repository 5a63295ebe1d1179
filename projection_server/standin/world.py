"""The stand-in robot's world, without ROS: what it is, how it is reset, how a plan runs.

The world is a robot (the knowledge base's Panda by default) at the table's near edge and
one object (an egg by default) on the table. Its *truth*, the object's properties, is drawn
at each :meth:`StandinWorld.reset` from the ranges of :class:`StandinConfig`, with the
object's place and the arm's start configuration, all from the reset's seed. A projection
server is not told the truth: it sees what the node publishes (joint positions, frames).

A plan runs as a projection does, by the same machinery (:class:`~projection_server.
simulation.runner.Projection`, the plan program, :func:`~projection_server.timeline.
translate_records`), on a scenario of the world as it is now (the arm's joint positions,
the object's pose) at :attr:`StandinConfig.physics_factor` times the projection's rate and
solver iterations; so ``slip``, ``break`` and ``lift`` mean on both sides what a timeline
says. It runs in the simulation's own process (:mod:`.simulation`), whose step hook
reports the world's state to an :class:`Observer` at :attr:`StandinConfig.state_hz` of
simulated time and, with ``real_time``, paces the simulation to the wall clock, as acting
takes a robot's time. The world after the plan is the world from then on::

    >>> world = StandinWorld()
    >>> drawn = world.reset(7)                      # the truth in drawn['object']
    >>> outcome = world.execute(parse_plan('[close_gripper(5)]'), observer)
    >>> outcome.events                              # e.g. ['...@0.52']
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import json
import math
import threading
import time
from typing import Any, Protocol, TYPE_CHECKING

import numpy as np

from projection_server import assets
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.geometry import quaternion_of_rpy, rpy_of
from projection_server.standin.description import matrix_of, RobotTree

if TYPE_CHECKING:
    from collections.abc import Sequence

    from projection_server.standin.plan_text import ParsedPlan

__all__ = ['Observer', 'Outcome', 'StandinConfig', 'StandinError', 'StandinWorld',
           'WorldState', 'event_text', 'world_json']

TABLE_TOP = 0.72   # m, the kitchen table's upper face
# The kitchen of the knowledge base (prolog/kb/kitchen.ttl): floor and table.
ENVIRONMENT = {
    'name': 'kitchen_env', 'class': 'environment',
    'pose': {'xyz': [0.0, 0.0, 0.0], 'rpy': [0.0, 0.0, 0.0]}, 'properties': {'gravity': 9.81},
    'parts': [
        {'name': 'floor1', 'class': 'floor', 'parts': [],
         'pose': {'xyz': [0.0, 0.0, 0.0], 'rpy': [0.0, 0.0, 0.0]},
         'properties': {'friction': 0.6, 'mass': 0.0, 'restitution': 0.1, 'shape': 'plane'}},
        {'name': 'table1', 'class': 'table', 'parts': [],
         'pose': {'xyz': [0.0, 0.0, 0.7], 'rpy': [0.0, 0.0, 0.0]},
         'properties': {'friction': 0.6, 'height': TABLE_TOP, 'mass': 0.0, 'restitution': 0.1,
                        'shape': 'box', 'size_x': 1.2, 'size_y': 0.8, 'size_z': 0.04}},
    ]}
# The knowledge base's panda_robot; its file is resolved in the asset directories.
ROBOT_FILE = 'franka_panda/panda.urdf'
ROBOT_BASE = (-0.68, 0.0, TABLE_TOP)
ROBOT = {'model': 'urdf', 'shape': 'none', 'tool_link': 'panda_hand',
         'tool_offset': [0.0, 0.0, 0.1034],
         'finger_joints': ['panda_finger_joint1', 'panda_finger_joint2'], 'max_force': 20.0}
HOME = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)   # the knowledge base's, arm joints
# The knowledge base's egg1 but the properties a reset draws.
EGG = {'shape': 'ellipsoid', 'length': 0.058, 'diameter': 0.044, 'restitution': 0.05,
       'rolling_friction': 0.001, 'spinning_friction': 0.001}
MIN_TOOL_HEIGHT = 0.12    # m above the table of the tool point at a start configuration
MIN_LINK_HEIGHT = 0.05    # m above the table of every link frame past the base's
MIN_EGG_DISTANCE = 0.15   # m from the egg's centre of the tool point and every link frame
MIN_HOME_DISTANCE = 0.2   # rad: a start configuration this far from HOME (the largest joint)


class StandinError(ProjectionError):
    """What the stand-in cannot do (kind ``invalid_request``, ``invalid_parameters``...)."""


@dataclass(frozen=True)
class StandinConfig:
    """The ranges a reset draws from (uniformly), and how the world runs.

    ``object_frame`` is the object's frame on ``/tf``; a plan may name the object by it or
    by ``object_name`` (its name in the events).
    """

    friction: tuple[float, float] = (0.1, 0.5)
    mass: tuple[float, float] = (0.05, 0.07)          # kg
    breaking_force: tuple[float, float] = (8.0, 12.0)   # N
    # m, the object's centre on the table. Nearer the base a top grasp's path leaves the
    # Panda's reach from some start configurations (5 of 30 seeds with x < -0.42); from
    # none of 60 within these.
    x: tuple[float, float] = (-0.40, -0.15)
    y: tuple[float, float] = (-0.2, 0.2)
    yaw: tuple[float, float] = (-0.3, 0.3)            # rad, of its long axis from world x
    joint_spread: float = 0.4      # rad: a start configuration is HOME + uniform(-s, s)
    physics_factor: int = 4        # times the projection's rate and solver iterations
    state_hz: float = 100.0        # reports of the state per simulated second
    real_time: bool = True
    robot_name: str = ''           # the robot's name in events ('': the URDF's, as robot_world)
    object_name: str = 'egg1'
    object_frame: str = 'egg_1'
    bag_dir: str = ''              # keep each execution's bag here ('' : none kept)

    def __post_init__(self) -> None:
        for key in ('friction', 'mass', 'breaking_force', 'x', 'y', 'yaw'):
            low, high = getattr(self, key)
            if not (math.isfinite(low) and math.isfinite(high) and low <= high):
                raise StandinError(ErrorKind.INVALID_PARAMETERS,
                                   f'{key}: a range [low, high], got {[low, high]}')
        for key in ('friction', 'mass', 'breaking_force'):
            if getattr(self, key)[0] <= 0:
                raise StandinError(ErrorKind.INVALID_PARAMETERS, f'{key}: must be positive')
        if not 1 <= self.physics_factor <= 8:
            raise StandinError(ErrorKind.INVALID_PARAMETERS,
                               f'physics_factor: 1 to 8, got {self.physics_factor}')
        if not 1.0 <= self.state_hz <= 1000.0:
            raise StandinError(ErrorKind.INVALID_PARAMETERS,
                               f'state_hz: 1 to 1000, got {self.state_hz}')


@dataclass(frozen=True)
class WorldState:
    """The world as a robot's sensors see it: joint positions (of the joints on
    ``/joint_states``), the object's pose (centre; quaternion x, y, z, w), and the
    simulated time of the last execution's sample (0 at a reset)."""

    joints: dict[str, float]
    object_xyz: tuple[float, float, float]
    object_quaternion: tuple[float, float, float, float]
    time: float = 0.0
    broken: bool = False


@dataclass
class Outcome:
    """What an execution did. ``ok`` False: ``error`` says why; the events are those until
    it stopped."""

    ok: bool
    error: str = ''
    events: list[str] = field(default_factory=list)
    timeline: dict[str, Any] = field(default_factory=dict)
    duration: float = 0.0      # s of wall time
    world_time: float = 0.0    # s simulated


class Observer(Protocol):
    """What the world tells while a plan runs (called from the executing thread)."""

    def state(self, state: WorldState) -> None:
        """The world's state, :attr:`StandinConfig.state_hz` times a simulated second."""

    def step(self, index: int, total: int, text: str) -> None:
        """Step ``index`` (1-based) of ``total`` begins."""

    def cancelled(self) -> bool:
        """Whether to stop (checked with each state)."""


class StandinWorld:
    """The stand-in's world: its truth and state, resets and executions. One execution or
    reset at a time (a lock); :attr:`state` may be read from any thread."""

    def __init__(self, config: StandinConfig | None = None):
        self.config = config or StandinConfig()
        status, path, message = assets.resolve(ROBOT_FILE)
        if status != 'ok':
            raise StandinError(ErrorKind.INVALID_SCENARIO, f'{ROBOT_FILE}: {message}')
        self.robot_file = path
        self.tree = RobotTree.from_file(path)
        if not self.config.robot_name:
            self.config = replace(self.config, robot_name=self.tree.name)
        self.base = matrix_of(ROBOT_BASE, (0.0, 0.0, 0.0, 1.0))
        self.arm_joints = [j for j in self.tree.state_joints if j not in ROBOT['finger_joints']]
        self.finger_joint = next(j for j in self.tree.state_joints
                                 if j in ROBOT['finger_joints'])
        self._lock = threading.Lock()
        self._process: Any = None   # the simulation's own process, started once
        self.truth: dict[str, float] = {}
        self.seed: int | None = None
        self.state: WorldState = WorldState({}, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        self.busy = False

    # --- reset --------------------------------------------------------------------------
    def reset(self, seed: int) -> dict[str, Any]:
        """A new world drawn from ``seed``; what was drawn (see ``ResetWorld.srv``)."""
        if not self._lock.acquire(blocking=False):
            raise StandinError(ErrorKind.INVALID_REQUEST, 'the robot is executing a plan')
        try:
            rng = np.random.default_rng(int(seed) & 0xFFFFFFFFFFFFFFFF)
            c = self.config
            truth = {'friction': float(rng.uniform(*c.friction)),
                     'mass': float(rng.uniform(*c.mass)),
                     'breaking_force': float(rng.uniform(*c.breaking_force))}
            xyz = (float(rng.uniform(*c.x)), float(rng.uniform(*c.y)),
                   TABLE_TOP + EGG['diameter'] / 2)
            yaw = float(rng.uniform(*c.yaw))
            joints = self._start_configuration(rng, xyz)
            self.truth, self.seed = truth, int(seed)
            self.state = WorldState(joints, xyz, quaternion_of_rpy(0.0, 0.0, yaw))
            return self.describe()
        finally:
            self._lock.release()

    def describe(self) -> dict[str, Any]:
        """The world now: its seed, the object (pose and truth), the joints."""
        state = self.state
        return {
            'seed': self.seed,
            'object': {'name': self.config.object_name, 'frame': self.config.object_frame,
                       'class': 'egg', 'broken': state.broken,
                       'pose': {'xyz': list(state.object_xyz),
                                'rpy': list(rpy_of(state.object_quaternion)),
                                'quaternion': list(state.object_quaternion)},
                       'properties': {**EGG, **self.truth}},
            'joints': {'names': list(state.joints), 'positions': list(state.joints.values())},
            'robot': {'name': self.config.robot_name, 'file': self.robot_file,
                      'base': list(ROBOT_BASE)},
        }

    def _start_configuration(self, rng: np.random.Generator,
                             egg: Sequence[float]) -> dict[str, float]:
        """Arm joints about HOME (clipped to their limits) that keep the hand above the
        table and off the egg, the fingers open; drawn until they do."""
        spread = self.config.joint_spread
        for _ in range(200):
            arm = [float(np.clip(h + rng.uniform(-spread, spread), *self._limits(name)))
                   for h, name in zip(HOME, self.arm_joints)]
            # Open: fingers held half closed would land on the egg of a plan that does not
            # open them first (the projection, reading them, would foresee it).
            finger = self._limits(self.finger_joint)[1]
            joints = {**dict(zip(self.arm_joints, arm)), self.finger_joint: finger}
            if max(abs(a - h) for a, h in zip(arm, HOME)) < MIN_HOME_DISTANCE:
                continue
            frames = self.tree.link_frames(self.base, joints)
            tool = frames[ROBOT['tool_link']] @ matrix_of(ROBOT['tool_offset'],
                                                          (0.0, 0.0, 0.0, 1.0))
            links = [m[:3, 3] for name, m in frames.items()
                     if name not in (self.tree.root, 'panda_link1')]
            if (tool[2, 3] > TABLE_TOP + MIN_TOOL_HEIGHT
                    and min(p[2] for p in links) > TABLE_TOP + MIN_LINK_HEIGHT
                    and min(math.dist(p, egg) for p in [*links, tool[:3, 3]])
                    > MIN_EGG_DISTANCE):
                return joints
        raise StandinError(ErrorKind.INVALID_PARAMETERS,
                           f'no start configuration within {spread} rad of home keeps the '
                           'hand above the table: give a smaller joint_spread')

    def _limits(self, joint: str) -> tuple[float, float]:
        return self.tree.joint(joint).limits

    # --- the scenario of the world now --------------------------------------------------
    def scenario(self) -> dict[str, Any]:
        """The scenario description (docs/contracts.md) of the world as it is now: the
        robot at its joint positions, the object at its pose with its true properties."""
        state = self.state
        robot = {**ROBOT, 'file': self.robot_file, 'joint_names': list(state.joints),
                 'joint_positions': list(state.joints.values())}
        egg = {**EGG, **self.truth}
        return {'name': 'standin', 'entities': [
            ENVIRONMENT,
            {'name': self.config.robot_name, 'class': 'robot', 'parts': [],
             'pose': {'xyz': list(ROBOT_BASE), 'rpy': [0.0, 0.0, 0.0]}, 'properties': robot},
            {'name': self.config.object_name, 'class': 'egg', 'parts': [],
             'pose': {'xyz': list(state.object_xyz),
                      'rpy': list(rpy_of(state.object_quaternion))},
             'properties': egg},
        ]}

    # --- executing a plan ---------------------------------------------------------------
    def execute(self, plan: ParsedPlan, observer: Observer) -> Outcome:
        """Run ``plan`` in the world as it is; the world after it is the world from then
        on. A plan that cannot run, or stops on the way, is an Outcome with ``ok`` False
        (never an exception): the robot keeps serving."""
        if not self._lock.acquire(blocking=False):
            return Outcome(False, 'the robot is executing another plan')
        started = time.monotonic()
        self.busy = True
        try:
            if not self.truth:
                return Outcome(False, 'the world has not been reset')
            if self.state.broken:
                return Outcome(False, f'{self.config.object_name} is broken: reset the world')
            template = self._renamed(plan.template)
            return self._run(template, plan.texts, observer, started)
        except ProjectionError as exc:
            return Outcome(False, exc.message, duration=time.monotonic() - started)
        finally:
            self.busy = False
            self._lock.release()

    def _renamed(self, template: list[Any]) -> list[Any]:
        """The plan's steps with the object named by its frame renamed to its name; an
        object the world does not have is an error."""
        c = self.config
        known = {c.object_name: c.object_name, c.object_frame: c.object_name}
        steps = []
        for index, step in enumerate(template):
            target = step.get('object') if isinstance(step, dict) else None
            if target is not None and target not in known:
                raise StandinError(ErrorKind.INVALID_SCENARIO,
                                   f'plan step {index + 1}: the robot sees no object '
                                   f'{target!r} (it sees {c.object_name}, frame '
                                   f'{c.object_frame})')
            steps.append({**step, 'object': known[target]} if target is not None else step)
        return steps

    def _run(self, template: list[Any], texts: list[str], observer: Observer,
             started: float) -> Outcome:
        from projection_server.standin.simulation import Execution, SimulationProcess
        if self._process is None:
            self._process = SimulationProcess()
        broken = self.state.broken

        def on_state(state: WorldState) -> None:
            self.state = replace(state, broken=broken)
        execution = Execution(self.scenario(), template, texts, self.config,
                              list(self.tree.state_joints))
        outcome, final = self._process.run(execution, observer, on_state)
        if final is not None:   # the world after the plan is the world from now on
            self.state = replace(final, broken=broken or final.broken)
        outcome.duration = time.monotonic() - started
        return outcome

    def warm_up(self) -> None:
        """Start the simulation process now, not at the first plan."""
        from projection_server.standin.simulation import SimulationProcess
        if self._process is None:
            self._process = SimulationProcess()
        self._process.start()

    def close(self) -> None:
        if self._process is not None:
            self._process.close()
            self._process = None


def event_text(event: Sequence[Any]) -> str:
    """``name(args)@start`` (a point) or ``name(args)@start-end``, times to 10 ms."""
    name, args, start, end = event
    head = f'{name}({", ".join(map(str, args))})' if args else str(name)
    if abs(end - start) < 1e-9:
        return f'{head}@{start:.2f}'
    return f'{head}@{start:.2f}-{end:.2f}'


def world_json(world: StandinWorld) -> str:
    """:meth:`StandinWorld.describe` as JSON."""
    return json.dumps(world.describe(), sort_keys=True)
