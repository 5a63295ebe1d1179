"""Inverse kinematics of a URDF arm: damped least squares on PyBullet's Jacobian, to a
tolerance.

PyBullet's own ``calculateInverseKinematics``, iterated, left position errors of 0.8 mm to
3 mm on the Panda's table-top poses (with joint limits given as its null space, 2-3 mm
after 50 rounds), so the arm is solved here instead: each iteration takes the tool's error
(position and rotation vector) and the Jacobian at the current joint values, steps by
``J^T (J J^T + lambda^2 I)^-1 e`` and clamps to the joint limits, until the error is below
:data:`POSITION_TOLERANCE` and :data:`ANGLE_TOLERANCE`. It reaches a few micrometres in 5-10
iterations from a nearby configuration (about 1 ms); a pose it cannot reach is reported, not
approximated.

The solver has a kinematic copy of the robot in a PyBullet client of its own (no world, no
dynamics), so solving never touches the simulated world. Copies are kept per process and
model file. :func:`load_robot` loads a robot's URDF or SDF (one model) with its base link's
frame at a pose, in the world and in the copy alike.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Sequence

import numpy as np

__all__ = ['ANGLE_TOLERANCE', 'Kinematics', 'POSITION_TOLERANCE', 'load_robot',
           'rotation_vector']

POSITION_TOLERANCE = 1e-4   # m
ANGLE_TOLERANCE = 1e-3      # rad
DAMPING = 0.01              # lambda of the damped least squares step
MAX_ITERATIONS = 100


def rotation_vector(q_from: Sequence[float], q_to: Sequence[float]) -> np.ndarray:
    """The rotation vector (axis times angle, world frame) that turns orientation ``q_from``
    into ``q_to`` (quaternions x, y, z, w)."""
    a, b = np.asarray(q_from, float), np.asarray(q_to, float)
    # q = q_to * conj(q_from): the world-frame rotation from one to the other
    ax, ay, az, aw = -a[0], -a[1], -a[2], a[3]
    bx, by, bz, bw = b
    x = bw * ax + bx * aw + by * az - bz * ay
    y = bw * ay - bx * az + by * aw + bz * ax
    z = bw * az + bx * ay - by * ax + bz * aw
    w = bw * aw - bx * ax - by * ay - bz * az
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return np.zeros(3)
    angle = 2.0 * math.atan2(s, w)
    return np.array([x, y, z]) * (angle / s)


def load_robot(client: Any, path: str, position: Sequence[float],
               orientation: Sequence[float], scale: float = 1.0, flags: int = 0) -> int:
    """Load the robot of the URDF or SDF ``path`` with its base fixed and its base link's
    frame at the pose; its body id (-1 if PyBullet cannot load it).

    An SDF is loaded whole (PyBullet places it at the pose its file gives), so it must hold
    one model, then moved: Bullet's base pose is the base link's centre of mass, so the
    pose given is composed with the base's inertial frame. A base with a mass is fixed to
    the world by a constraint (PyBullet fixes a massless base itself).

    Raises:
        ValueError: an SDF of more than one model (its message says how many).
    """
    if not str(path).lower().endswith('.sdf'):
        return client.loadURDF(path, position, orientation, useFixedBase=True,
                               globalScaling=scale, flags=flags)
    try:
        bodies = client.loadSDF(path, globalScaling=scale)
    except Exception:   # pybullet.error: the file cannot be loaded
        return -1
    if len(bodies) != 1:
        for body in bodies:
            client.removeBody(body)
        raise ValueError(f'it holds {len(bodies)} models, a robot is one')
    body = bodies[0]
    inertial = client.getDynamicsInfo(body, -1)
    base = client.multiplyTransforms(position, orientation, inertial[3], inertial[4])
    client.resetBasePositionAndOrientation(body, *base)
    if inertial[0] > 0:
        client.createConstraint(body, -1, -1, -1, client.JOINT_FIXED, (0, 0, 0),
                                (0, 0, 0), base[0], (0, 0, 0, 1), base[1])
    return body


class Kinematics:
    """The kinematic copy of one robot: its URDF or SDF at its base pose, a tool frame on
    a link (``tool_offset`` and ``tool_orientation`` in the link's frame).

    ``joints`` are the joint indices the solver moves (the arm); the others stay at their
    values in :meth:`solve`'s ``seed``.
    """

    def __init__(self, urdf: str, base: tuple[Any, Any], tool_link: int,
                 tool_offset: Sequence[float], joints: Sequence[int], scale: float = 1.0,
                 tool_orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0)):
        self.client = _client()
        self.body = load_robot(self.client, urdf, base[0], base[1], scale)
        self.tool_link = tool_link
        self.tool_offset = tuple(float(v) for v in tool_offset)
        self.tool_orientation = tuple(float(v) for v in tool_orientation)
        self.joints = list(joints)
        c, body = self.client, self.body
        self.movable = [j for j in range(c.getNumJoints(body))
                        if c.getJointInfo(body, j)[2] != c.JOINT_FIXED]
        self._columns = [self.movable.index(j) for j in self.joints]
        info = [c.getJointInfo(body, j) for j in self.joints]
        lower = np.array([i[8] for i in info], float)
        upper = np.array([i[9] for i in info], float)
        free = upper < lower   # continuous joints have no limits
        self.lower = np.where(free, -np.inf, lower)
        self.upper = np.where(free, np.inf, upper)

    def close(self) -> None:
        self.client.removeBody(self.body)

    def __deepcopy__(self, memo: dict[int, Any]) -> Kinematics:
        # One solver per robot and base serves the process's projections (each solve sets
        # every joint it reads), copies of a projection too; its PyBullet connection cannot
        # be copied: a copy's client would disconnect the one they share when collected.
        return self

    def tool_pose(self, values: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """The tool point's world pose with the movable joints at ``values``."""
        c, body = self.client, self.body
        for j, v in zip(self.movable, values):
            c.resetJointState(body, j, v)
        state = c.getLinkState(body, self.tool_link, computeForwardKinematics=True)
        position, orientation = c.multiplyTransforms(state[4], state[5], self.tool_offset,
                                                     self.tool_orientation)
        return np.asarray(position), np.asarray(orientation)

    def solve(self, position: Sequence[float], orientation: Sequence[float],
              seed: Sequence[float]) -> tuple[np.ndarray, float, float]:
        """Joint values of the movable joints that put the tool at the pose, starting from
        ``seed`` (the movable joints' current values); and the remaining position [m] and
        angle [rad] errors (below the tolerances when the pose is reached)."""
        c, body = self.client, self.body
        target = np.asarray(position, float)
        q = np.asarray(seed, float).copy()
        zeros = [0.0] * len(q)
        lam2 = DAMPING * DAMPING
        for _ in range(MAX_ITERATIONS):
            current, rotation = self.tool_pose(q)
            error = np.concatenate([target - current, rotation_vector(rotation, orientation)])
            position_error = float(np.linalg.norm(error[:3]))
            angle_error = float(np.linalg.norm(error[3:]))
            if position_error < POSITION_TOLERANCE and angle_error < ANGLE_TOLERANCE:
                break
            linear, angular = c.calculateJacobian(body, self.tool_link, self.tool_offset,
                                                  list(q), zeros, zeros)
            jacobian = np.vstack([np.asarray(linear), np.asarray(angular)])[:, self._columns]
            step = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + lam2 * np.eye(6),
                                                error)
            q[self._columns] = np.clip(q[self._columns] + step, self.lower, self.upper)
        return q, position_error, angle_error


@functools.cache
def _client() -> Any:
    """This process's client for kinematic copies (DIRECT, no gravity, never stepped)."""
    import pybullet

    from projection_server.simulation.physics import bound_client

    return bound_client(pybullet.DIRECT)
