"""``grasp_object(force, position, lift_time)``: grasp the egg on the table and lift it.

The gripper approaches horizontally along the egg's long axis with open fingers, the pads'
centre ``position`` metres from the egg's centre along that axis, closes its fingers with the
grip ``force`` of each finger, waits, lifts the egg by 0.1 m in ``lift_time`` seconds (a
minimum-jerk motion, peak acceleration 5.77 x 0.1 m / lift_time^2) and holds it there.
Nothing in the program looks at the outcome: whether the egg is held, slips or breaks is
decided by the contacts' friction and by the egg's object model. The pads hold an egg of mass
m with friction mu through the lift iff 2 mu force >= m (g + a): a quicker lift needs more
friction.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.programs.registry import Parameter, Program, register
from projection_server.simulation.world import settle

if TYPE_CHECKING:
    from projection_server.simulation.physics import Gripper, Physics
    from projection_server.simulation.scenario import Scenario

__all__ = ['GraspObject', 'PROGRAM']

TARGET_CLASS = 'egg'
APPROACH_DISTANCE = 0.09   # m, pre-grasp offset of the tool along the approach axis
OPEN_WIDTH = 0.07          # m between the pads while approaching
CLOSING_SPEED = 0.03       # m/s of each finger
LIFT_HEIGHT = 0.10         # m
# Phase ends [s]: settle, approach, close, squeeze; the lift takes ``lift_time``, the hold
# HOLD_TIME after it.
SETTLED, APPROACHED, CLOSED, SQUEEZED = 0.2, 0.8, 1.5, 1.8
HOLD_TIME = 1.0


def _min_jerk(t: float, start: float, end: float) -> tuple[float, float]:
    """Progress 0..1 of a minimum-jerk motion between times ``start`` and ``end``, and its
    rate [1/s]."""
    s = min(max((t - start) / (end - start), 0.0), 1.0)
    return (s * s * s * (10.0 - 15.0 * s + 6.0 * s * s),
            30.0 * s * s * (1.0 - s) * (1.0 - s) / (end - start))


class GraspObject:
    """The task: one grasp of the scenario's first egg with its first robot's gripper."""

    def __init__(self, physics: Physics, scenario: Scenario, params: dict[str, float],
                 rng: np.random.Generator):
        target = next(scenario.of_class(TARGET_CLASS), None)
        robot = next(scenario.of_class('robot'), None)
        if target is None or robot is None:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'grasp_object needs an {TARGET_CLASS} and a robot')
        self.force = params['force']
        self.lifted = SQUEEZED + params['lift_time']
        self.duration = self.lifted + HOLD_TIME
        self.phases = (('settle', SETTLED), ('approach', APPROACHED), ('close', CLOSED),
                       ('squeeze', SQUEEZED), ('lift', self.lifted), ('hold', self.duration))
        self.gripper: Gripper = physics.grippers[robot.name]
        self._physics, self._robot, self._target = physics, robot.name, target.name
        settle(physics)   # the egg lies at rest before the gripper is placed beside it
        position, orientation = physics.pose(target.name)
        rot = physics.rotation_matrix(orientation)
        yaw = math.atan2(rot[1, 0], rot[0, 0])   # heading of the egg's long axis
        axis = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        grasp = np.asarray(position) + params['position'] * axis
        self.gripper.place(tuple(grasp), physics.quaternion_from_euler((0, 0, yaw)),
                           approach=APPROACH_DISTANCE, lift=0.0, opening=OPEN_WIDTH)
        # The gantry is given its targets at every physics step, with the speeds at which
        # they move: targets that jumped at the control rate made the pads' speed jump at
        # every control step, in one physics step, an acceleration that grew with the rate
        # (14 m/s^2 at 240 Hz, 68 at 960 Hz, against the lift's 0.58): the egg slid in the
        # pads at every jump, and the grip force that held it depended on the time step.
        self._rate = physics.settings.physics.rate_hz
        self._commanded: tuple[float, ...] | None = None
        self._follow()
        physics.step_hooks.append(self._follow)

    def _follow(self) -> None:
        """The gantry's targets of the next physics step (after each step)."""
        t = (self._physics.step_count + 1) / self._rate
        approach, approach_rate = _min_jerk(t, SETTLED, APPROACHED)
        lift, lift_rate = _min_jerk(t, SQUEEZED, self.lifted)
        target = (APPROACH_DISTANCE * (1.0 - approach), LIFT_HEIGHT * lift,
                  -APPROACH_DISTANCE * approach_rate, LIFT_HEIGHT * lift_rate)
        if target != self._commanded:   # at rest between the motions: nothing to send
            self._commanded = target
            self.gripper.move(*target)

    def control(self, physics: Physics) -> None:
        if self._closes(physics.step_count):
            self.gripper.close(self.force, CLOSING_SPEED)

    def _closes(self, step: int) -> bool:
        """Whether the control step ``step`` (the world at it) closes the fingers."""
        return (step % self._physics.settings.control.steps_per_control == 0
                and self._physics.time >= APPROACHED and self.gripper.command != 'close')

    def command_at(self, params: dict[str, float], step: int) -> float | None:
        """The grip force that ``params`` command from the step after ``step`` on; None
        before the fingers close: grasps that differ only in their force step alike
        until then (:mod:`~projection_server.simulation.branching`)."""
        if self.gripper.command == 'close' or self._closes(step):
            return params['force']
        return None

    def retarget(self, params: dict[str, float]) -> None:
        """Go on with the force of ``params`` (the fingers have not closed yet)."""
        self.force = params['force']

    def state(self) -> list[tuple[str, int, str, str]]:
        """``(robot, -1, phase, egg)``: the phase under way (``phases``)."""
        t = self._physics.time
        phase = next((name for name, end in self.phases if t < end), 'hold')
        return [(self._robot, -1, phase, self._target)]


PROGRAM = register(Program(
    name='grasp_object',
    params=(
        Parameter('force', 'N', 0.1, 50.0, 5.0, 'grip force of each finger'),
        Parameter('position', 'm', -0.04, 0.04, 0.0,
                  'centre of the gripper pads relative to the centre of the egg, '
                  'along its long axis'),
        Parameter('lift_time', 's', 0.1, 10.0, 1.0,
                  'duration of the lift by 0.1 m (minimum jerk)'),
    ),
    create=GraspObject,
    doc=__doc__.splitlines()[0],
    # The position places the gripper and the lift time sets the schedule; the force acts
    # only when the fingers close, at 0.8 s of the grasp's 3.8 s: a copy of a MuJoCo world
    # pays for that, a fork of a PyBullet worker does not (bench/RESULTS.md).
    setup_params=('position', 'lift_time'),
    forks=False,
    engines=('pybullet', 'mujoco'),
))
