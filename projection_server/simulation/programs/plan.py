"""``plan``: a control program written in the query, as a list of motion primitives.

A plan is data: a list of steps, each a dict with an ``action`` and its arguments, in which
any number may be a parameter reference ``{"param": name}``; a projection grounds it with
its parameters' values. Prolog's ``plan([...])`` (prolog/plan.pl) is turned into this form
and checked there first; :func:`check_plan` checks it again here, as for a job from any
client. The actions (``[]``: optional):

* ``move_to``: the tool point to an ``object``'s position (at the step's start) plus an
  ``offset`` in world axes, or to a ``pose`` (``position``, ``orientation`` a quaternion x, y,
  z, w); [``speed`` m/s], [``angular_speed`` rad/s], [``orientation``: ``top``,
  ``["top", yaw]`` or ``["side", yaw]``];
* ``move_by``: the tool point by an ``offset`` (world axes) [, ``speed``, ``angular_speed``,
  ``orientation``];
* ``rotate_by``: the tool frame about an ``axis`` (``x``, ``y``, ``z`` or a vector, world
  axes) through the tool point by an ``angle`` [rad] [, ``angular_speed``];
* ``open_gripper``; ``close_gripper`` with a ``force`` [N]; ``wait`` ``seconds``.

A number may also be an arithmetic expression of numbers and parameters, ``{"expr": [op,
a, b]}`` with ``op`` one of ``+ - * /`` (``["-", a]``: minus ``a``).

Tool frame conventions (:mod:`projection_server.simulation.robots.manipulator`): z is the
way the fingers point, y the way they close. ``top``: the fingers point down and close along
world y (``["top", yaw]``: that turned by yaw about world z). ``["side", yaw]``: the fingers
point horizontally at heading yaw (0: world +x) and close horizontally. Of the two tool
orientations that do so (half a turn apart about the fingers) the one asked for is taken,
unless the other is clearly nearer (:data:`FLIP_MARGIN`).
Without an orientation a move keeps the tool's orientation. Motions are straight lines of the tool
point with a minimum-jerk profile whose mean speed is ``speed`` (default
:data:`DEFAULT_SPEED`), turning the tool at a mean ``angular_speed`` (default
:data:`DEFAULT_TURN_SPEED`); a step takes as long as the slower of the two needs. The
fingers close at :data:`CLOSING_SPEED` each, pushing with at most the force; the step ends
when they have stopped. They open to the gripper's full opening. A step's *target* is the
object it names, else that of the last step that named one (what the robot is meant to
touch; the timeline's ``collision`` excludes it).

Bounds: at most :data:`MAX_STEPS` steps, and :data:`MAX_DURATION` seconds of simulated time.
Before anything runs, a plan is refused only if it cannot finish in time: by
:func:`plan_bound`, the time its steps take at the least (a ``move_by`` its exact length
at its speed, a ``rotate_by`` its angle, a ``wait`` its seconds; a ``move_to`` and a gripper
step may take no time, since where the tool starts is not known before the world is
built). A plan that runs past the limit stops there with a :class:`PlanTooLong` naming the
step it reached. When its steps are done the plan waits until the world has been at rest
for :data:`REST_TIME` (at most :data:`SETTLE_AFTER` s), so
that what it let go of lands. Nothing in the interpreter looks at the outcome.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Sequence, TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.geometry import quaternion_product
from projection_server.simulation.programs.registry import Program, register
from projection_server.simulation.world import settle

if TYPE_CHECKING:
    from collections.abc import Mapping

    from projection_server.simulation.physics import Physics
    from projection_server.simulation.robots.manipulator import Manipulator
    from projection_server.simulation.scenario import Scenario

__all__ = ['ACTIONS', 'PROGRAM', 'PlanTask', 'PlanTooLong', 'check_plan', 'ground',
           'plan_bound']

MAX_STEPS = 100
MAX_DURATION = 120.0       # s of simulated time a plan's steps may take
GRIPPER_TIME = 2.0         # s a gripper step may take at most
SETTLE_AFTER = 3.0         # s the world may take to come to rest after the last step
DEFAULT_SPEED = 0.1        # m/s
DEFAULT_TURN_SPEED = 1.0   # rad/s
MAX_SPEED, MAX_TURN_SPEED = 2.0, 2 * math.pi   # m/s, rad/s
MAX_FORCE = 1000.0         # N a close_gripper may ask for (the gripper caps it lower)
CLOSING_SPEED = 0.03       # m/s of each finger
OPENING_SPEED = 0.1        # m/s of each finger
FINGERS_STILL = (0.1, 2e-4)   # the fingers have stopped: moved < 0.2 mm in 0.1 s
REST_SPEED = 0.01          # m/s below which a body is at rest (a falling one is faster
REST_TIME = 0.1            # from its first sample); and for how long the world must be
FLIP_MARGIN = 0.1          # rad by which a half-turned grasp must be nearer to be taken

class PlanTooLong(ProjectionError):
    """A plan that cannot finish, or did not finish, within :data:`MAX_DURATION` s of
    simulated time."""

    def __init__(self, message: str):
        super().__init__(ErrorKind.PLAN_DURATION, message)

    def __reduce__(self):
        return (type(self), (self.message,))


# action -> (required arguments, optional arguments)
ACTIONS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    'move_to': ((), ('object', 'offset', 'pose', 'speed', 'angular_speed', 'orientation')),
    'move_by': (('offset',), ('speed', 'angular_speed', 'orientation')),
    'rotate_by': (('axis', 'angle'), ('angular_speed',)),
    'open_gripper': ((), ()),
    'close_gripper': (('force',), ()),
    'wait': (('seconds',), ()),
}
_AXES = {'x': (1.0, 0.0, 0.0), 'y': (0.0, 1.0, 0.0), 'z': (0.0, 0.0, 1.0)}


# --- the plan as data ---------------------------------------------------------------------

def check_plan(plan: Any, params: Mapping[str, float]) -> list[dict[str, Any]]:
    """The plan ``plan`` grounded with ``params``, checked: its steps, their arguments and
    values, the parameters it names (each given) and its bounds.

    Raises:
        ProjectionError: kind ``invalid_parameters``, saying which step and why.
    """
    if not isinstance(plan, list) or not plan:
        _invalid('a plan is a non-empty list of steps')
    if len(plan) > MAX_STEPS:
        _invalid(f'a plan has at most {MAX_STEPS} steps, this one {len(plan)}')
    used = set()
    steps = []
    for index, step in enumerate(plan):
        used |= _references(step)
        steps.append(_checked_step(index, ground(step, params, index)))
    unknown = sorted(used - set(params))
    if unknown:
        _invalid(f'the plan names parameters that are not given: {", ".join(unknown)}')
    bound = plan_bound(steps)
    if bound > MAX_DURATION:
        raise PlanTooLong(f'the plan takes at least {bound:.0f} s of simulated time, more '
                          f'than {MAX_DURATION:.0f} s: its moves by offsets, turns and waits '
                          'alone take that long at their speeds')
    return steps


def ground(value: Any, params: Mapping[str, float], index: int | None = None) -> Any:
    """``value`` with each ``{"param": name}`` replaced by that parameter's value and each
    ``{"expr": [op, a, b]}`` (``+ - * /``; ``["-", a]``) by its value."""
    if isinstance(value, dict):
        if set(value) == {'param'}:
            name = value['param']
            if name not in params:
                return value   # reported by check_plan
            return params[name]
        if set(value) == {'expr'}:
            return _evaluate(value['expr'], params, index)
        return {k: ground(v, params, index) for k, v in value.items()}
    if isinstance(value, list):
        return [ground(v, params, index) for v in value]
    return value


def _evaluate(expr: Any, params: Mapping[str, float], index: int | None) -> Any:
    where = f'plan step {index + 1}' if index is not None else 'plan'
    if not isinstance(expr, list) or not 2 <= len(expr) <= 3 or expr[0] not in _OPERATORS:
        _invalid(f'{where}: not an arithmetic expression: {expr!r}')
    args = [ground(a, params, index) for a in expr[1:]]
    if not all(_number(a) for a in args):
        return {'expr': [expr[0], *args]}   # an unknown parameter: reported by check_plan
    if len(args) == 1:
        if expr[0] != '-':
            _invalid(f'{where}: {expr[0]} needs two operands')
        return -args[0]
    a, b = args
    if expr[0] == '/' and b == 0:
        _invalid(f'{where}: division by zero')
    return {'+': a + b, '-': a - b, '*': a * b, '/': a / b if b else 0.0}[expr[0]]


_OPERATORS = ('+', '-', '*', '/')


def plan_bound(steps: Sequence[Mapping[str, Any]]) -> float:
    """The fewest simulated seconds a grounded plan's steps can take (see the module doc)."""
    total = 0.0
    for step in steps:
        action = step['action']
        if action == 'move_by':
            total += math.dist(step['offset'], (0.0, 0.0, 0.0)) / step.get('speed',
                                                                             DEFAULT_SPEED)
        elif action == 'rotate_by':
            total += abs(step['angle']) / step.get('angular_speed', DEFAULT_TURN_SPEED)
        elif action == 'wait':
            total += step['seconds']
    return total


def _references(value: Any) -> set[str]:
    if isinstance(value, dict):
        if set(value) == {'param'}:
            return {str(value['param'])}
        return set().union(*map(_references, value.values()))
    if isinstance(value, list):
        return set().union(*map(_references, value))
    return set()


def _checked_step(index: int, step: Any) -> dict[str, Any]:
    where = f'plan step {index + 1}'
    if not isinstance(step, dict) or step.get('action') not in ACTIONS:
        action = step.get('action') if isinstance(step, dict) else step
        _invalid(f'{where}: unknown action {action!r} (known: {", ".join(ACTIONS)})')
    action = step['action']
    required, optional = ACTIONS[action]
    given = set(step) - {'action'}
    missing = sorted(set(required) - given)
    extra = sorted(given - set(required) - set(optional))
    if missing or extra:
        _invalid(f'{where}: {action} ' + (f'needs {", ".join(missing)}' if missing else
                                          f'has no argument {", ".join(extra)}'))
    out: dict[str, Any] = {'action': action}
    for key in given:
        out[key] = _argument(where, action, key, step[key])
    if action == 'move_to':
        if ('pose' in out) == ('object' in out):
            _invalid(f'{where}: move_to goes to an object or to a pose')
        if 'pose' in out and ('offset' in out or 'orientation' in out):
            _invalid(f'{where}: move_to a pose takes no offset or orientation')
        if 'object' in out:
            out.setdefault('offset', (0.0, 0.0, 0.0))
    return out


def _argument(where: str, action: str, key: str, value: Any) -> Any:
    if key == 'object':
        if not isinstance(value, str) or not value:
            _invalid(f'{where}: object must be an entity name, got {value!r}')
        return value
    if key in ('offset', 'position'):
        return _vector(where, key, value)
    if key == 'pose':
        if not isinstance(value, dict) or set(value) != {'position', 'orientation'}:
            _invalid(f'{where}: pose has a position and an orientation')
        q = np.asarray(_numbers(where, 'orientation', value['orientation'], 4))
        norm = float(np.linalg.norm(q))
        if norm < 1e-9:
            _invalid(f'{where}: the orientation quaternion is zero')
        return {'position': _vector(where, 'position', value['position']),
                'orientation': tuple(float(v) for v in q / norm)}
    if key == 'orientation':
        if value == 'top':
            return ('top', 0.0)
        if (isinstance(value, list) and len(value) == 2 and value[0] in ('top', 'side')
                and _number(value[1])):
            return (value[0], float(value[1]))
        _invalid(f'{where}: orientation is top, [top, Yaw] or [side, Yaw], got {value!r}')
    if key == 'axis':
        if isinstance(value, str) and value in _AXES:
            return _AXES[value]
        axis = np.asarray(_vector(where, 'axis', value))
        if np.linalg.norm(axis) < 1e-9:
            _invalid(f'{where}: the axis is zero')
        return tuple(float(v) for v in axis / np.linalg.norm(axis))
    number = _scalar(where, key, value)
    limits = {'speed': (0.0, MAX_SPEED), 'angular_speed': (0.0, MAX_TURN_SPEED),
              'force': (0.0, MAX_FORCE), 'seconds': (0.0, MAX_DURATION),
              'angle': (-4 * math.pi, 4 * math.pi)}[key]
    low, high = limits
    if not (low < number <= high) and not (key == 'angle' and low <= number <= high):
        _invalid(f'{where}: {key} = {number:g} is outside ({low:g}, {high:g}]')
    return number


def _number(value: Any) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def _scalar(where: str, key: str, value: Any) -> float:
    if not _number(value):
        _invalid(f'{where}: {key} must be a number, got {value!r}')
    return float(value)


def _numbers(where: str, key: str, value: Any, size: int) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)) or len(value) != size or not all(
            map(_number, value)):
        _invalid(f'{where}: {key} must be a list of {size} numbers, got {value!r}')
    return tuple(float(v) for v in value)


def _vector(where: str, key: str, value: Any) -> tuple[float, float, float]:
    return _numbers(where, key, value, 3)


def _invalid(message: str):
    raise ProjectionError(ErrorKind.INVALID_PARAMETERS, message)


# --- the interpreter ----------------------------------------------------------------------

def _min_jerk(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def _path(start: tuple[np.ndarray, np.ndarray], goal: tuple[np.ndarray, np.ndarray]
          ) -> Callable[[float], tuple[tuple[float, ...], tuple[float, ...]]]:
    """The pose at progress ``s`` (0..1) of the straight line from ``start`` to ``goal``,
    its orientation turned on the great circle between theirs; in plain floats."""
    (x0, y0, z0), (x1, y1, z1) = map(tuple, (start[0], goal[0]))
    q0, q1 = np.asarray(start[1], float), np.asarray(goal[1], float)
    dot = float(np.dot(q0, q1))
    if dot < 0.0:
        q1, dot = -q1, -dot
    a = tuple(map(float, q0))
    b = tuple(map(float, q1))
    theta = math.acos(min(1.0, dot))
    sin_theta = math.sin(theta)

    def pose(s: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        position = (x0 + (x1 - x0) * s, y0 + (y1 - y0) * s, z0 + (z1 - z0) * s)
        if sin_theta < 1e-6:
            return position, b if s >= 1.0 else a
        wa, wb = math.sin((1 - s) * theta) / sin_theta, math.sin(s * theta) / sin_theta
        return position, tuple(wa * u + wb * v for u, v in zip(a, b))
    return pose


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return 2.0 * math.acos(min(1.0, abs(float(np.dot(a, b)))))


def _orientation(kind: str, yaw: float) -> np.ndarray:
    """The tool orientation of ``top``/``side`` at ``yaw`` (see the module doc)."""
    c, s = math.cos(yaw), math.sin(yaw)
    if kind == 'top':   # z down, y = world y turned by yaw
        y = (-s, c, 0.0)
        z = (0.0, 0.0, -1.0)
    else:               # z at heading yaw, y horizontal to its left
        z = (c, s, 0.0)
        y = (-s, c, 0.0)
    x = np.cross(y, z)
    matrix = np.column_stack([x, y, z])
    return _quaternion(matrix)


def _quaternion(m: np.ndarray) -> np.ndarray:
    """The unit quaternion (x, y, z, w) of rotation matrix ``m``."""
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    q = np.asarray(q)
    return q / np.linalg.norm(q)


class PlanTask:
    """The task: the plan's steps one after the other, on the scenario's robot."""

    duration = MAX_DURATION + SETTLE_AFTER

    def __init__(self, physics: Physics, scenario: Scenario, params: dict[str, float],
                 rng: np.random.Generator, plan: list[Any]):
        robots = list(physics.manipulators.values())
        if len(robots) != 1:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'a plan needs a scenario with one robot, this has '
                                  f'{len(robots)}')
        self.robot: Manipulator = robots[0]
        self._physics = physics
        self._template = plan
        self._grounded: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
        self.steps = self._ground(params)
        names = {e.name for e in scenario.entities}
        for index, step in enumerate(self.steps):
            if step.get('object') is not None and step['object'] not in names:
                raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                      f'plan step {index + 1}: no entity {step["object"]!r} '
                                      'in the scenario')
        settle(physics)   # the world at rest before the robot moves
        self._rate = physics.settings.physics.rate_hz
        self.index = -1
        self.target = ''              # the object the current step is about
        self._motion: tuple[Any, ...] | None = None   # (start time, duration, path)
        self._still: float | bool | None = None
        self._started = 0.0
        self._openings: list[tuple[float, float]] = []
        self._done_at: float | None = None
        self._rest_since: float | None = None
        position, orientation = self.robot.tool_pose()
        self._pose = (np.asarray(position, float), np.asarray(orientation, float))
        if self.robot.every_step:
            physics.step_hooks.append(self._follow)

    # --- trees (simulation.branching) ---------------------------------------------------
    def _ground(self, params: Mapping[str, float]) -> list[dict[str, Any]]:
        key = tuple(sorted(params.items()))
        steps = self._grounded.get(key)
        if steps is None:
            steps = self._grounded[key] = check_plan(self._template, params)
        return steps

    def command_at(self, params: dict[str, float], step: int) -> Any:
        """What ``params`` make the robot do next: the step under way and the one after
        it, grounded (equal for parametrizations that step alike until then)."""
        steps = self._ground(params)
        index = max(self.index, 0)
        return (index, repr(steps[index:index + 2]))

    def retarget(self, params: dict[str, float]) -> None:
        """Go on with the steps of ``params`` from the current one (the same so far)."""
        self.steps = self._ground(params)

    # --- running ------------------------------------------------------------------------
    def state(self) -> list[tuple[str, int, str, str]]:
        """``(robot, step index, action, target)`` of the step under way."""
        action = self.steps[self.index]['action'] if 0 <= self.index < len(self.steps) else ''
        return [(self.robot.name, self.index, action, self.target)]

    def control(self, physics: Physics) -> None:
        t = physics.time
        while self.index < len(self.steps) and (self.index < 0 or self._step_done(t)):
            self.index += 1
            if self.index < len(self.steps):
                self._start(self.steps[self.index], t)
            elif self._done_at is None:
                self._done_at = t
        if self._done_at is None and t > MAX_DURATION:
            self._too_long()
        self._move(t)

    def _too_long(self):
        step = self.steps[self.index]
        what = step['action'] + (f' {step["object"]}' if step.get('object') else '')
        raise PlanTooLong(f'the plan ran past {MAX_DURATION:.0f} s of simulated time in step '
                          f'{self.index + 1} of {len(self.steps)} ({what}, begun at '
                          f'{self._started:.1f} s): give its motions a higher speed, or '
                          'project it in parts')

    def _move(self, t: float) -> None:
        """Servo the tool to the motion's pose at time ``t`` (in plain floats: it runs at
        every physics step)."""
        motion = self._motion
        if motion is None:
            if self._still is not True:
                self.robot.servo(*self._pose)
                self._still = True
            return
        start, duration, path = motion
        s = _min_jerk((t - start) / duration)
        if s == self._still:   # the motion's end, reached before
            return
        self._still = s if s >= 1.0 else None
        self._pose = path(s)
        self.robot.servo(*self._pose)

    def _follow(self) -> None:
        """After each physics step: the pose of the next step, for a robot that takes it
        every step."""
        self._move((self._physics.step_count + 1) / self._rate)

    def finished(self, physics: Physics) -> bool:
        """The steps are done and the world has been at rest for :data:`REST_TIME` (or had
        :data:`SETTLE_AFTER` for it)."""
        if self._done_at is None:
            return False
        t = physics.time
        if t >= self._done_at + SETTLE_AFTER:
            return True
        if all(math.hypot(*physics.base_velocity(b.body_id)[0]) < REST_SPEED
               for b in physics.bodies.values()
               if not b.static and not b.driven and b.group is None):
            if self._rest_since is None:
                self._rest_since = t
            return t - self._rest_since >= REST_TIME - 1e-9
        self._rest_since = None
        return False

    def _start(self, step: dict[str, Any], t: float) -> None:
        action = step['action']
        self._started = t
        self._motion = None
        self._still = None   # True: the tool is at rest; 1.0: at a motion's end
        if step.get('object') is not None:
            self.target = step['object']
        gripper = self.robot.gripper
        if action in ('move_to', 'move_by', 'rotate_by'):
            goal = self._goal(step)
            what = f'the goal of plan step {self.index + 1} ({action})'
            self.robot.check_reach(*goal, what)
            distance = float(np.linalg.norm(goal[0] - self._pose[0]))
            turn = _angle(goal[1], self._pose[1])
            duration = max(distance / step.get('speed', DEFAULT_SPEED),
                           turn / step.get('angular_speed', DEFAULT_TURN_SPEED))
            self._motion = (t, max(duration, 1.0 / self._rate), _path(self._pose, goal))
        elif action == 'open_gripper':
            gripper.open(gripper.max_opening, OPENING_SPEED)
        elif action == 'close_gripper':
            gripper.close(step['force'], CLOSING_SPEED)
            self._openings = []

    def _goal(self, step: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        position, orientation = self._pose
        action = step['action']
        if action == 'rotate_by':
            axis = np.asarray(step['axis'])
            half = step['angle'] / 2
            turn = np.array([*(axis * math.sin(half)), math.cos(half)])
            return position, quaternion_product(turn, orientation)
        if 'orientation' in step:
            # A parallel gripper grasps alike turned half a turn about its fingers: the
            # other one if it is clearly nearer (by FLIP_MARGIN; a tie keeps the one asked).
            wanted = _orientation(*step['orientation'])
            flipped = quaternion_product(wanted, np.array([0.0, 0.0, 1.0, 0.0]))
            if _angle(flipped, orientation) < _angle(wanted, orientation) - FLIP_MARGIN:
                wanted = flipped
            orientation = wanted
        if action == 'move_by':
            return position + np.asarray(step['offset']), orientation
        if 'pose' in step:
            return (np.asarray(step['pose']['position']),
                    np.asarray(step['pose']['orientation']))
        centre = np.asarray(self._physics.pose(step['object'])[0])
        return centre + np.asarray(step['offset']), orientation

    def _step_done(self, t: float) -> bool:
        step = self.steps[self.index]
        action = step['action']
        elapsed = t - self._started
        if action == 'wait':
            return elapsed >= step['seconds'] - 0.5 / self._rate
        if self._motion is not None:
            start, duration = self._motion[0], self._motion[1]
            return t >= start + duration - 0.5 / self._rate
        opening = self.robot.gripper.opening()
        if action == 'open_gripper':
            return (opening >= self.robot.gripper.max_opening - 1e-3
                    or elapsed >= GRIPPER_TIME)
        # close_gripper: the fingers have stopped moving
        self._openings.append((t, opening))
        window, still = FINGERS_STILL
        past = [o for s, o in self._openings if s <= t - window]
        if elapsed >= GRIPPER_TIME:
            return True
        return bool(past) and abs(past[-1] - opening) < still


PROGRAM = register(Program(
    name='plan',
    params=(),
    create=PlanTask,
    doc=__doc__.splitlines()[0],
    setup_params=(),
    takes_plan=True,
    engines=('pybullet', 'mujoco'),
))
