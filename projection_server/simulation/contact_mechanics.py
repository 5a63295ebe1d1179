"""Contact pressure on an ellipsoidal shell: the computation behind the egg's breaking.

Rigid-body physics reports *forces*; a shell breaks under *pressure*. This module estimates
the peak contact pressure on an ellipsoid from a measured normal force and the contact's
geometry, and converts it into an *equivalent load*: the force that would give the same
peak pressure in the reference test that defines an egg's ``breaking_force`` (squeezed at
its equator between two flat faces). Far from edges the equivalent load is the force scaled
by the shell's local curvature; at a pad's edge it is higher because the contact patch is cut.

Model: the counter-surface is an elastic layer on a rigid backing (a Winkler foundation,
modulus ``k`` = E / thickness [N/m^3]), the right model for a thin rubber gripper pad. The
pressure at a point is ``k * max(0, delta - gap)``, where ``gap`` is the distance from the
undeformed face to the shell and ``delta`` the indentation. For an unbounded face this gives
``p_max = sqrt(k F / (pi R_e))`` with ``R_e = sqrt(R_1 R_2)`` the geometric mean of the
shell's principal radii (``R_e = a b c sum(x_i^2 / a_i^4)`` on an ellipsoid); the reference
test at the equator of a spheroid has ``R_e = a``. On a finite pad the part of the patch
beyond the pad's edge is missing, so ``delta``, and with it ``p_max``, must rise to carry
the same force: the integral is solved numerically over the pad face. Once the shell's
deepest point lies beyond the face, the shell rests on the pad's rounded rim instead, a
contact with the rim's curvature added across it.

Scaling the load with ``R_e`` (rather than the ``R_e^2`` of Hertz's half-space pressure)
agrees with Auerbach's law for the fracture of brittle solids under curved indenters, whose
critical load is proportional to the indenter's radius.
"""

from __future__ import annotations

import functools
import math
from typing import Sequence

import numpy as np

__all__ = [
    'curvature_load',
    'ellipsoid_gaps',
    'equivalent_load',
    'pad_peak_pressure',
    'reference_radius',
    'rim_peak_pressure',
    'support_point',
    'winkler_indentation',
]

_GRID = 40            # grid points per axis of the pad window
_MIN_ACTIVE = 80      # fewer loaded grid points than this: refine the window
_HEAD = 400           # gaps sorted at first: more than a patch of a grid window loads


def reference_radius(semi_axes: tuple[float, float, float]) -> float:
    """``R_e`` of the breaking-force test: pressed along the 2nd axis at the equator."""
    a, b, c = semi_axes
    return a * c / b


def equivalent_load(peak_pressure: float, stiffness: float,
                    semi_axes: tuple[float, float, float]) -> float:
    """Force of the reference test that gives ``peak_pressure`` [N]."""
    return math.pi * reference_radius(semi_axes) * peak_pressure ** 2 / stiffness


def curvature_load(force: float, semi_axes: tuple[float, float, float],
                   point: Sequence[float]) -> float:
    """Equivalent load of ``force`` on an unbounded flat face touching ``point`` (shell frame).

    ``point`` is projected onto the ellipsoid first (Bullet reports contact points on the
    collision margin). Plain float arithmetic: it runs for every contact in every step.
    """
    a0, a1, a2 = semi_axes
    x0, x1, x2 = point
    # Sums written out (the same additions, in the same order, as sum() of the terms).
    scale = math.sqrt((x0 / a0) ** 2 + (x1 / a1) ** 2 + (x2 / a2) ** 2)
    if scale == 0.0:
        return force
    radius = a0 * a1 * a2 * ((x0 / scale) ** 2 / a0 ** 4 + (x1 / scale) ** 2 / a1 ** 4
                             + (x2 / scale) ** 2 / a2 ** 4)
    return force * (a0 * a2 / a1) / radius


def support_point(semi_axes: tuple[float, float, float], rot: np.ndarray, pos: np.ndarray,
                  normal: np.ndarray) -> np.ndarray:
    """World point of the ellipsoid whose outward normal is ``normal`` (world, unit)."""
    d2 = np.asarray(semi_axes) ** 2
    m = rot.T @ normal
    local = d2 * m / math.sqrt(float(m @ (d2 * m)))
    return pos + rot @ local


def ellipsoid_gaps(semi_axes: tuple[float, float, float], rot: np.ndarray, pos: np.ndarray,
                   points: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Distance from each of ``points`` (N x 3, world) along ``direction`` to the ellipsoid.

    ``inf`` where the ray misses it. Exact (no quadratic approximation of the surface).
    """
    inv = 1.0 / np.asarray(semi_axes)
    x0 = ((points - pos) @ rot) * inv
    d = (rot.T @ direction) * inv
    qa = float(d @ d)
    qb = 2.0 * (x0 @ d)
    qc = np.einsum('ij,ij->i', x0, x0) - 1.0
    disc = qb * qb - 4.0 * qa * qc
    hit = disc >= 0.0
    # Where the ray hits, the root of the disc itself (no masked copies of the arrays).
    return np.where(hit, (-qb - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * qa), np.inf)


def rim_peak_pressure(force: float, semi_axes: tuple[float, float, float], rot: np.ndarray,
                      pos: np.ndarray, edge_point: np.ndarray, edge_direction: np.ndarray,
                      face_normal: np.ndarray, stiffness: float,
                      rim_radius: float) -> float | None:
    """Peak pressure [Pa] of the shell resting on a pad's rounded rim.

    The rim is a cylinder of ``rim_radius`` along ``edge_direction`` through ``edge_point``;
    the shell touches it where the face normal through the edge meets the shell. The
    contact's radii are the shell's normal curvature radius along the rim and, across it,
    the shell's and the rim's curvatures combined; then ``p = sqrt(k F / (pi R_e))``.
    """
    gap = ellipsoid_gaps(semi_axes, rot, pos, edge_point[None, :], face_normal)[0]
    if not math.isfinite(gap):
        return None
    inv2 = 1.0 / np.asarray(semi_axes) ** 2
    point = rot.T @ (edge_point + gap * face_normal - pos)
    gradient = point * inv2
    normal = gradient / np.linalg.norm(gradient)
    along = rot.T @ edge_direction
    along = along - (along @ normal) * normal
    along /= np.linalg.norm(along)
    across = np.cross(normal, along)

    def curvature(t: np.ndarray) -> float:
        return float(t @ (t * inv2)) / float(np.linalg.norm(gradient))

    radius = 1.0 / math.sqrt(curvature(along) * (curvature(across) + 1.0 / rim_radius))
    return math.sqrt(stiffness * force / (math.pi * radius))


def winkler_indentation(gaps: np.ndarray, cell_area: float, force: float,
                        stiffness: float) -> tuple[float, int]:
    """Indentation ``delta`` with ``k * cell_area * sum(max(0, delta - gap)) = force``.

    Returns ``(delta, number of loaded cells)``. Exact for the discretized face: with the
    gaps sorted, the force is piecewise linear in ``delta``.
    """
    g = gaps[np.isfinite(gaps)]
    if g.size == 0:
        return math.inf, 0
    # Only the smallest gaps can be loaded: sorted, they are the first ones of the whole
    # sort, and so are their cumulative sums. Unless the balance lies beyond them, that is
    # the answer of the full sort, to the bit; otherwise the full sort gives it.
    for head in (_HEAD, g.size):
        if head < g.size:
            part = np.partition(g, head)[:head + 1]
            part.sort()
        else:
            part = np.sort(g)
        n = min(head, g.size)
        ranked = part[:n]
        delta = (force / (stiffness * cell_area) + np.cumsum(ranked)) / _ranks(n)
        upper = np.append(part[1:n], np.inf) if n == g.size else part[1:n + 1]
        below = delta <= upper
        first = int(np.argmax(below))
        if below[first]:
            return float(delta[first]), first + 1
    raise AssertionError('the force balances below the largest gap')   # pragma: no cover


@functools.lru_cache(maxsize=8)
def _ranks(n: int) -> np.ndarray:
    return np.arange(1, n + 1)


def pad_peak_pressure(force: float, semi_axes: tuple[float, float, float], rot: np.ndarray,
                      pos: np.ndarray, face_centre: np.ndarray, face_axes: np.ndarray,
                      face_normal: np.ndarray, half_extents: tuple[float, float],
                      stiffness: float, rim_radius: float) -> float | None:
    """Peak pressure [Pa] of a rectangular rubber pad pressed onto the ellipsoid.

    ``face_normal`` points from the pad towards the shell; ``face_axes`` (2 x 3) span the flat
    face with ``half_extents``; its rim is rounded with ``rim_radius``. While the shell's
    deepest point lies over the face, the pressure field is solved on a window of the face
    around it, grown until the loaded patch fits and refined until it is resolved. Beyond the
    face the shell rests on the rim: a contact of the shell with a cylinder of the rim's
    radius (:func:`rim_peak_pressure`). Returns None if the pad is not over the shell.
    """
    if force <= 0.0:
        return 0.0
    # The face's two coordinates as plain floats: on two numbers numpy's calls cost more
    # than the comparisons, and clipping, absolute values and differences are exact in both.
    h0, h1 = half_extents
    support = support_point(semi_axes, rot, pos, -face_normal)
    o0, o1 = (face_axes @ (support - face_centre)).tolist()
    c0 = -h0 if o0 < -h0 else h0 if o0 > h0 else o0
    c1 = -h1 if o1 < -h1 else h1 if o1 > h1 else o1
    if abs(o0) > h0 or abs(o1) > h1:
        # Along the rim: the face axis whose extent the deepest point does not exceed (or
        # exceeds least, at a corner).
        along = 0 if abs(o0) - h0 <= abs(o1) - h1 else 1
        edge_point = face_centre + face_axes.T @ np.array([c0, c1])
        return rim_peak_pressure(force, semi_axes, rot, pos, edge_point, face_axes[along],
                                 face_normal, stiffness, rim_radius)
    a_max, b_min = max(semi_axes), min(semi_axes)
    # Patch radius of a full contact at the most curved spot: a safe first window.
    delta = math.sqrt(force / (math.pi * stiffness * b_min ** 2 / a_max))
    radius = math.sqrt(2.0 * a_max ** 2 / b_min * delta)
    if h0 - abs(o0) > 1.5 * radius and h1 - abs(o1) > 1.5 * radius:
        # The whole patch lies on the face: the closed form of an unbounded face holds.
        local = rot.T @ (support - pos)
        load = curvature_load(force, semi_axes, local)
        return math.sqrt(load * stiffness / (math.pi * reference_radius(semi_axes)))
    half = 2.0 * radius + max(abs(o0 - c0), abs(o1 - c1))
    grown = False
    for _ in range(12):
        lo = np.array([max(c0 - half, -h0), max(c1 - half, -h1)])
        hi = np.array([min(c0 + half, h0), min(c1 + half, h1)])
        # Both axes at once: the same floats as np.linspace of each (a test compares).
        u, v = _linspace(lo, hi).T
        points = _grid_points(face_centre, face_axes, u, v)
        gaps = ellipsoid_gaps(semi_axes, rot, pos, points, face_normal)
        if not np.isfinite(gaps).any():
            return None
        cell = (u[1] - u[0]) * (v[1] - v[0]) if _GRID > 1 else 0.0
        if cell <= 0.0:
            half *= 2.0
            continue
        delta, active = winkler_indentation(gaps, cell, force, stiffness)
        loaded = (gaps < delta).reshape(_GRID, _GRID)
        cut = [lo[0] > -h0, hi[0] < h0, lo[1] > -h1, hi[1] < h1]
        edges = [loaded[0, :], loaded[-1, :], loaded[:, 0], loaded[:, -1]]
        if any(c and e.any() for c, e in zip(cut, edges)):
            half *= 1.6
            grown = True
            continue
        if active < _MIN_ACTIVE and not grown:
            half *= 0.5
            continue
        break
    return stiffness * (delta - float(gaps[np.isfinite(gaps)].min()))


def _linspace(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``np.linspace(lo, hi, _GRID)``, the same floats (numpy's steps, start and end), without
    its checks and conversions."""
    y = _steps(_GRID) * ((hi - lo) / (_GRID - 1)) + lo
    y[-1] = hi
    return y


@functools.lru_cache(maxsize=4)
def _steps(n: int) -> np.ndarray:
    return np.arange(n, dtype=float)[:, None]


def _grid_points(centre: np.ndarray, axes: np.ndarray, u: np.ndarray,
                 v: np.ndarray) -> np.ndarray:
    """The points ``centre + u[i] axes[0] + v[j] axes[1]`` (row i * len(v) + j), added in
    that order, as from a meshgrid of ``u`` and ``v``, but from the rows of the terms."""
    return ((centre + u[:, None] * axes[0])[:, None, :]
            + (v[:, None] * axes[1])[None, :, :]).reshape(-1, 3)
