"""Pure geometry of a deformable body's side: which way its plane's normal points.

The plane of a body made of segments is fitted to the segments' positions (SVD of the
centred positions; the normal is the singular vector of the smallest singular value, as in
Haidu et al.'s simulation analyses). Its sign is fixed by the segment-ordering convention of
:mod:`projection_server.simulation.objects.pancake`: the upper side's normal is along
``(a - c) x (b - c)`` with ``c`` the root segment and ``a``, ``b`` the two reference rim
segments (a quarter turn apart, counter-clockwise seen from the upper side).
"""

from __future__ import annotations

import numpy as np

__all__ = ['UPSIDE_DOWN_MAX_Z', 'is_upside_down', 'upper_normal']

UPSIDE_DOWN_MAX_Z = -0.5   # upside down: the upper side's normal at least 60 deg below level


def upper_normal(positions: np.ndarray, centre: np.ndarray, ref_a: np.ndarray,
                 ref_b: np.ndarray) -> np.ndarray:
    """Unit normal of the plane fitted to ``positions`` (n x 3), on the upper side."""
    points = np.asarray(positions, dtype=float).reshape(-1, 3)
    _, _, vt = np.linalg.svd(points - points.mean(axis=0))
    normal = vt[-1]
    # np.cross's products and differences in plain floats (the same numbers, without its
    # per-call overhead on 3-vectors).
    ax, ay, az = (float(a - c) for a, c in zip(ref_a, centre))
    bx, by, bz = (float(b - c) for b, c in zip(ref_b, centre))
    reference = np.array([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])
    return -normal if normal @ reference < 0 else normal


def is_upside_down(normal: np.ndarray) -> bool:
    """Whether a body whose upper side's normal is ``normal`` lies upside down."""
    return bool(normal[2] <= UPSIDE_DOWN_MAX_Z)
