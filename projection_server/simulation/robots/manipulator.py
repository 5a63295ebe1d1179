"""Robots whose tool point a plan moves: :class:`Manipulator` and its two kinds.

Conventions of the tool frame (every robot's, so that plans carry over): its origin, the
*tool point*, is midway between the finger pads; its z axis is the approach direction, the
way the fingers point; its y axis is the direction along which the fingers close. A plan
moves the tool point along straight lines with a minimum-jerk profile and turns the tool
frame about the tool point (:mod:`projection_server.simulation.programs.plan`); a robot
follows the pose it is given at every control step with its joints' position control and a
force limit, so a robot that pushes against something pushes with at most that force.

* :class:`FloatingTool`: a gripper without an arm held at the tool pose by a constraint,
  the PR2's gripper: it reaches every pose within its reach and turns any way.
* :class:`Arm`: a URDF arm, its joints found by damped least squares
  (:mod:`.kinematics`); a pose the solver cannot reach within its tolerance is an error
  of kind ``unreachable``.

Each is PyBullet's; what every engine's shares is in :class:`FloatingToolBase` and
:class:`ArmBase`, so that an engine's own says only how it reads and moves its joints.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Sequence, TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.robots.kinematics import Kinematics

if TYPE_CHECKING:
    from projection_server.simulation.physics import Gripper, GripperBase

__all__ = ['Arm', 'ArmBase', 'FloatingTool', 'FloatingToolBase', 'Manipulator',
           'REACH_TOLERANCE']

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
    # Given the tool's pose at every physics step, not only at control steps: a target that
    # jumps at the control rate shakes what the tool holds, the more the finer the step.
    every_step = False

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


class FloatingToolBase(Manipulator):
    """What every engine's floating tool shares: a gripper ``body_id`` with no arm that
    reaches every pose within ``reach`` of ``home``'s position (m, along each axis; z from
    ``reach[2][0]`` to ``reach[2][1]``), is given its pose at every physics step and
    remembers the pose it was last given. An engine's floating tool says where the tool is
    (:meth:`tool_pose`) and how it is moved to a new pose (:meth:`_move`)."""

    every_step = True

    def __init__(self, name: str, body_id: int, gripper: GripperBase, home: Sequence[float],
                 reach: tuple[tuple[float, float], ...]):
        self.name = name
        self.body_id = body_id
        self.gripper = gripper
        self._home = np.asarray(home, float)
        self._reach = reach
        self._target: tuple[tuple[float, ...], tuple[float, ...]] | None = None

    def check_reach(self, position: Sequence[float], orientation: Sequence[float],
                    what: str) -> None:
        offset = np.asarray(position, float) - self._home
        low = np.array([-self._reach[0][1], -self._reach[1][1], self._reach[2][0]])
        high = np.array([self._reach[0][1], self._reach[1][1], self._reach[2][1]])
        outside = float(np.maximum(low - offset, offset - high).max())
        if outside > 0:
            raise _unreachable(self.name, what, position, outside, 0.0)

    def servo(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        target = (tuple(map(float, position)), tuple(map(float, orientation)))
        if target == self._target:
            return
        self._target = target
        self._move(*target)

    def _move(self, position: tuple[float, ...], orientation: tuple[float, ...]) -> None:
        """Hold the tool at the pose from now on."""
        raise NotImplementedError


class FloatingTool(FloatingToolBase):
    """A floating tool (:class:`FloatingToolBase`) on PyBullet, held at the tool pose by a
    fixed constraint whose frame moves, pushing with at most ``force``. ``tool`` is the tool
    frame in the body's root link frame.

    The constraint corrects ``gain`` of its error per physics step (the fraction of a
    tracking rate per second, so that the tool follows alike at any time step), as the
    gantry's position control does.
    """

    def __init__(self, client: Any, name: str, body_id: int, gripper: Gripper,
                 tool: tuple[Sequence[float], Sequence[float]], home: Sequence[float],
                 reach: tuple[tuple[float, float], ...], force: float, gain: float):
        super().__init__(name, body_id, gripper, home, reach)
        self._client = client
        self._force, self._gain = force, gain
        c = client
        # Bullet's base frame is the root link's centre of mass: the tool in that frame.
        inertial = c.getDynamicsInfo(body_id, -1)[3:5]
        self._tool_in_base = c.multiplyTransforms(*c.invertTransform(*inertial), *tool)
        self._base_in_tool = c.invertTransform(*self._tool_in_base)
        position, orientation = self.tool_pose()
        self._constraint = c.createConstraint(
            body_id, -1, -1, -1, c.JOINT_FIXED, (0.0, 0.0, 0.0), self._tool_in_base[0],
            position, self._tool_in_base[1], orientation)
        self.servo(position, orientation)

    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        c = self._client
        base = c.getBasePositionAndOrientation(self.body_id)
        position, orientation = c.multiplyTransforms(*base, *self._tool_in_base)
        return np.asarray(position), np.asarray(orientation)

    def _move(self, position: tuple[float, ...], orientation: tuple[float, ...]) -> None:
        self._client.changeConstraint(self._constraint, position, orientation,
                                      maxForce=self._force, erp=self._gain)


class ArmBase(Manipulator):
    """What every engine's arm shares: a URDF (or SDF) arm ``body_id``, loaded at ``base``
    (its base link's frame), with its tool point ``tool_offset`` from link ``tool_link`` and
    the tool frame turned by ``tool_orientation`` from the link's; ``joints`` are the arm's
    joints (the fingers are the gripper's). One solver on one kinematic copy finds the
    joints of a pose, whatever the engine. An engine's arm says how its joints are read
    (:meth:`_now`) and given their targets (:meth:`_command`), and sets ``_home`` to the
    joints it starts at once it can read them."""

    _home: np.ndarray   # the joints where the arm started

    def __init__(self, name: str, body_id: int, gripper: GripperBase, urdf: str, scale: float,
                 base: tuple[Sequence[float], Sequence[float]], joints: Sequence[int],
                 tool_link: int, tool_offset: Sequence[float],
                 tool_orientation: Sequence[float]):
        self.name = name
        self.body_id = body_id
        self.gripper = gripper
        self.kinematics = _kinematics(urdf, (tuple(base[0]), tuple(base[1])), tool_link,
                                      tuple(tool_offset), tuple(joints), scale,
                                      tuple(tool_orientation))
        self._joints = self.kinematics.movable
        self._arm = list(joints)
        self._target: tuple[tuple[float, ...], tuple[float, ...]] | None = None
        self._solution: np.ndarray | None = None

    def _now(self) -> list[float]:
        """The movable joints' values now (``kinematics.movable``'s order)."""
        raise NotImplementedError

    def _command(self, values: list[float]) -> None:
        """Drive the arm's joints (``joints``' order) to ``values`` from now on."""
        raise NotImplementedError

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
        self._command([solution[self._joints.index(j)] for j in self._arm])


class Arm(ArmBase):
    """An arm (:class:`ArmBase`) on PyBullet: its joints' position control, with their
    URDF force limits and the position gain ``gain``."""

    def __init__(self, client: Any, name: str, body_id: int, urdf: str, scale: float,
                 base: tuple[Sequence[float], Sequence[float]], joints: Sequence[int],
                 tool_link: int, tool_offset: Sequence[float], gripper: Gripper,
                 gain: float, tool_orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0)):
        # ``base`` is the pose the URDF was loaded at (Bullet's own base pose is the base
        # link's centre of mass).
        super().__init__(name, body_id, gripper, urdf, scale, base, joints, tool_link,
                         tool_offset, tool_orientation)
        self._client = client
        self._forces = [client.getJointInfo(body_id, j)[10] for j in self._arm]
        self._gain = gain
        self._home = np.asarray(self._now())

    def _now(self) -> list[float]:
        return [s[0] for s in self._client.getJointStates(self.body_id, self._joints)]

    def _command(self, values: list[float]) -> None:
        self._client.setJointMotorControlArray(
            self.body_id, self._arm, self._client.POSITION_CONTROL, targetPositions=values,
            forces=self._forces, positionGains=[self._gain] * len(self._arm))


@functools.lru_cache(maxsize=8)
def _kinematics(urdf: str, base: tuple[Any, Any], tool_link: int,
                tool_offset: tuple[float, ...], joints: tuple[int, ...],
                scale: float, tool_orientation: tuple[float, ...]) -> Kinematics:
    """A kinematic copy per robot and base pose, kept for the process's next projections."""
    return Kinematics(urdf, base, tool_link, tool_offset, joints, scale, tool_orientation)
