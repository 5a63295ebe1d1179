"""Rotations as the simulation and the timeline both need them, without a physics client."""

from __future__ import annotations

import math

import numpy as np

__all__ = ['quaternion_of', 'quaternion_of_rpy', 'quaternion_product', 'rpy_of']


def quaternion_of(m: np.ndarray) -> tuple[float, float, float, float]:
    """``(x, y, z, w)`` of rotation matrix ``m``, with w >= 0."""
    w = math.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2,
                      m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2,
                      m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2,
                      m[1, 0] - m[0, 1])
    return (x, y, z, w)


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The quaternion product a * b, each ``(x, y, z, w)``."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def rpy_of(q) -> tuple[float, float, float]:
    """Roll, pitch, yaw [rad] of the quaternion ``(x, y, z, w)``: the rotation is yaw about
    z after pitch about y after roll about x (fixed axes), as PyBullet's and URDF's rpy."""
    x, y, z, w = (float(v) for v in q)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return (roll, pitch, yaw)


def quaternion_of_rpy(roll: float, pitch: float, yaw: float
                      ) -> tuple[float, float, float, float]:
    """``(x, y, z, w)`` of fixed-axis roll, pitch, yaw: :func:`rpy_of`'s inverse."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)
