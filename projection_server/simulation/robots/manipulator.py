"""Robots whose tool point a plan moves: :class:`Manipulator` and its two kinds.

Conventions of the tool frame (every robot's, so that plans carry over): its origin, the
*tool point*, is midway between the finger pads; its z axis is the approach direction, the
way the fingers point; its y axis is the direction along which the fingers close. A plan
moves the tool point along straight lines with a minimum-jerk profile and turns the tool
frame about the tool point (:mod:`projection_server.simulation.programs.plan`); a robot
follows the pose it is given at every control step with its joints' position control and a
force limit, so a robot that pushes against something pushes with at most that force.

* :class:`CartesianGantry`: a gripper carried by six position-controlled joints (x, y, z,
  then yaw, roll, pitch), the PR2's gripper without its arm: it reaches every pose in its
  joints' ranges, and its inverse kinematics is closed form.
* :class:`Arm`: a URDF arm, its joints found by damped least squares
  (:mod:`.kinematics`); a pose the solver cannot reach within its tolerance is an error
  of kind ``unreachable``.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Sequence, TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.robots.kinematics import Kinematics

if TYPE_CHECKING:
    from projection_server.simulation.physics import Gripper

__all__ = ['Arm', 'CartesianGantry', 'Manipulator', 'REACH_TOLERANCE']

# How close a solved pose must come to the one asked for: ten times the solver's own
# tolerances (kinematics.POSITION_TOLERANCE, ANGLE_TOLERANCE), which it meets wherever it
# converges.
REACH_TOLERANCE = (1e-3, 1e-2)   # m, rad


class Manipulator:
    """A robot with a tool point and a gripper: :meth:`servo` it to a tool pose at every
    control step, open and close its :attr:`gripper`."""

    name: str
    body_id: int
    gripper: Gripper

    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """The tool point's world position and orientation (x, y, z, w) now."""
        raise NotImplementedError

    def servo(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Command the joints to put the tool at the pose.

        Raises:
            ProjectionError: kind ``unreachable`` if the robot cannot.
        """
        raise NotImplementedError

    def check_reach(self, position: Sequence[float], orientation: Sequence[float],
                    what: str) -> None:
        """Raise ProjectionError ``unreachable`` (naming ``what``) if the tool cannot be
        put at the pose."""
        raise NotImplementedError


def _unreachable(robot: str, what: str, position: Sequence[float], error: float,
                 angle: float) -> ProjectionError:
    xyz = ', '.join(f'{v:.3f}' for v in position)
    return ProjectionError(ErrorKind.UNREACHABLE,
                           f'{robot} cannot reach {what}: tool point [{xyz}] m is missed by '
                           f'{error * 1000:.1f} mm and {math.degrees(angle):.1f} deg')


class CartesianGantry(Manipulator):
    """A tool carried by six joints of ``body_id``: ``joints`` x, y, z (prismatic, along the
    base's axes), then yaw (z), roll (x), pitch (y) (revolute); the tool frame is the pitch
    joint's child link frame. Its zero is the base frame."""

    def __init__(self, client: Any, name: str, body_id: int, joints: Sequence[int],
                 tool_link: int, gripper: Gripper, force: float, torque: float, gain: float):
        self.name = name
        self.body_id = body_id
        self.gripper = gripper
        self._client = client
        self._joints = list(joints)
        self._tool_link = tool_link
        self._forces = [force] * 3 + [torque] * 3
        self._gain = gain
        self._base = client.getBasePositionAndOrientation(body_id)
        self._base_inverse = client.invertTransform(*self._base)
        info = [client.getJointInfo(body_id, j) for j in self._joints[:3]]
        self._lower = np.array([i[8] for i in info])
        self._upper = np.array([i[9] for i in info])
        self._target: tuple[tuple[float, ...], tuple[float, ...]] | None = None

    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        state = self._client.getLinkState(self.body_id, self._tool_link,
                                          computeForwardKinematics=True)
        return np.asarray(state[4]), np.asarray(state[5])

    def joint_values(self, position: Sequence[float],
                     orientation: Sequence[float]) -> list[float]:
        """The six joint values that put the tool at the pose (angles nearest the joints'
        values now, so the tool turns the short way)."""
        c = self._client
        local, turn = c.multiplyTransforms(*self._base_inverse, position, orientation)
        r = np.asarray(c.getMatrixFromQuaternion(turn)).reshape(3, 3)
        # R = Rz(yaw) Rx(roll) Ry(pitch)
        roll = math.asin(max(-1.0, min(1.0, r[2, 1])))
        pitch = math.atan2(-r[2, 0], r[2, 2])
        yaw = math.atan2(-r[0, 1], r[1, 1])
        now = [s[0] for s in c.getJointStates(self.body_id, self._joints[3:])]
        angles = [a + 2 * math.pi * round((b - a) / (2 * math.pi))
                  for a, b in zip((yaw, roll, pitch), now)]
        return [*local, *angles]

    def check_reach(self, position: Sequence[float], orientation: Sequence[float],
                    what: str) -> None:
        values = np.asarray(self.joint_values(position, orientation)[:3])
        outside = np.maximum(self._lower - values, values - self._upper).max()
        if outside > 0:
            raise _unreachable(self.name, what, position, float(outside), 0.0)

    def servo(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        target = (tuple(position), tuple(orientation))
        if target == self._target:
            return
        self._target = target
        values = self.joint_values(position, orientation)
        self._client.setJointMotorControlArray(
            self.body_id, self._joints, self._client.POSITION_CONTROL, targetPositions=values,
            forces=self._forces, positionGains=[self._gain] * 6)


class Arm(Manipulator):
    """A URDF arm ``body_id``, loaded at ``base``, with its tool point ``tool_offset`` from
    link ``tool_link``; ``joints`` are the arm's joints (the fingers are the gripper's)."""

    def __init__(self, client: Any, name: str, body_id: int, urdf: str, scale: float,
                 base: tuple[Sequence[float], Sequence[float]], joints: Sequence[int],
                 tool_link: int, tool_offset: Sequence[float], gripper: Gripper,
                 gain: float):
        self.name = name
        self.body_id = body_id
        self.gripper = gripper
        self._client = client
        # ``base`` is the pose the URDF was loaded at (its base link's frame; Bullet's own
        # base pose is the base link's centre of mass).
        self.kinematics = _kinematics(urdf, (tuple(base[0]), tuple(base[1])), tool_link,
                                      tuple(tool_offset), tuple(joints), scale)
        self._joints = self.kinematics.movable
        self._arm = list(joints)
        self._forces = [client.getJointInfo(body_id, j)[10] for j in self._arm]
        self._gain = gain
        self._target: tuple[tuple[float, ...], tuple[float, ...]] | None = None
        self._solution: np.ndarray | None = None
        self._home = np.asarray(self._now())   # where the arm started

    def _now(self) -> list[float]:
        return [s[0] for s in self._client.getJointStates(self.body_id, self._joints)]

    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self.kinematics.tool_pose(self._now())

    def _solve(self, position: Sequence[float], orientation: Sequence[float],
               seed: Sequence[float], what: str) -> np.ndarray:
        # Damped least squares may stall at a joint limit from one start: a pose is
        # unreachable only if it is from the joints now, from the home pose and from the
        # middle of the joints' ranges.
        best = None
        for start in (seed, self._home, self._middle()):
            values, error, angle = self.kinematics.solve(position, orientation, start)
            if error <= REACH_TOLERANCE[0] and angle <= REACH_TOLERANCE[1]:
                return values
            if best is None or error < best[0]:
                best = (error, angle)
        raise _unreachable(self.name, what, position, *best)

    def _middle(self) -> np.ndarray:
        k = self.kinematics
        middle = np.asarray(self._home, float).copy()
        columns = [k.movable.index(j) for j in k.joints]
        finite = np.isfinite(k.lower) & np.isfinite(k.upper)
        middle[columns] = np.where(finite, (k.lower + k.upper) / 2, middle[columns])
        return middle

    def check_reach(self, position: Sequence[float], orientation: Sequence[float],
                    what: str) -> None:
        self._solve(position, orientation, self._now(), what)

    def servo(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        target = (tuple(position), tuple(orientation))
        if target == self._target:
            return
        # Solved from the last solution (or the joints now): the next pose of a path is
        # near the last, so the solver takes a few iterations and stays on one branch.
        seed = self._solution if self._solution is not None else self._now()
        solution = self._solve(position, orientation, seed, 'a pose of its path')
        self._target, self._solution = target, solution
        values = [solution[self._joints.index(j)] for j in self._arm]
        self._client.setJointMotorControlArray(
            self.body_id, self._arm, self._client.POSITION_CONTROL, targetPositions=values,
            forces=self._forces, positionGains=[self._gain] * len(self._arm))


@functools.lru_cache(maxsize=8)
def _kinematics(urdf: str, base: tuple[Any, Any], tool_link: int,
                tool_offset: tuple[float, ...], joints: tuple[int, ...],
                scale: float) -> Kinematics:
    """A kinematic copy per robot and base pose, kept for the process's next projections."""
    return Kinematics(urdf, base, tool_link, tool_offset, joints, scale)
