"""Measures of a poured particle fluid (Kunze et al. 2011, Table II), pure numpy.

Positions are world positions [m] of the particles, shape ``(n, 3)``. Example::

    >>> maker = Disc(centre=(0.0, 0.0), top=0.75, radius=0.15)
    >>> xy = on_disc(positions, maker, particle_radius=0.005)
    >>> centroid_offset(positions[xy, :2], maker.centre), roundness(positions[xy, :2])
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = [
    'Disc',
    'PILE_HEIGHT',
    'Vessel',
    'centroid_offset',
    'in_vessel',
    'on_disc',
    'principal_axes',
    'reached_level',
    'roundness',
    'spread_area',
]

PILE_HEIGHT = 0.05   # m above a disc's top within which particles count as lying on it


@dataclass(frozen=True)
class Disc:
    """A horizontal surface: centre (x, y), height of its top and radius [m]."""

    centre: tuple[float, float]
    top: float
    radius: float


@dataclass(frozen=True)
class Vessel:
    """The inside of an open container at a pose: a cylinder of ``radius`` from ``bottom``
    to ``rim`` along the z axis of the frame (``position``, 3x3 ``rotation``)."""

    position: Sequence[float]
    rotation: np.ndarray
    radius: float
    bottom: float
    rim: float


def on_disc(positions: np.ndarray, disc: Disc, particle_radius: float,
            pile_height: float = PILE_HEIGHT) -> np.ndarray:
    """Mask of the particles lying on ``disc``: over it (centre within its radius plus a
    particle radius) and at most ``pile_height`` above its top."""
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    distance = np.hypot(p[:, 0] - disc.centre[0], p[:, 1] - disc.centre[1])
    return ((distance <= disc.radius + particle_radius)
            & (p[:, 2] >= disc.top) & (p[:, 2] <= disc.top + pile_height))


def in_vessel(positions: np.ndarray, vessel: Vessel, particle_radius: float) -> np.ndarray:
    """Mask of the particles inside ``vessel`` (its volume grown by a particle radius)."""
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    local = (p - np.asarray(vessel.position, dtype=float)) @ np.asarray(vessel.rotation)
    return ((np.hypot(local[:, 0], local[:, 1]) <= vessel.radius + particle_radius)
            & (local[:, 2] >= vessel.bottom - particle_radius)
            & (local[:, 2] <= vessel.rim + particle_radius))


def reached_level(positions: np.ndarray, level: float) -> np.ndarray:
    """Mask of the particles whose centres are at or below ``level`` [m] (e.g. on the table
    or the floor when ``level`` is just above the table top)."""
    return np.asarray(positions, dtype=float).reshape(-1, 3)[:, 2] <= level


def centroid_offset(xy: np.ndarray, centre: Sequence[float]) -> tuple[float, float] | None:
    """Centroid of the points ``xy`` (n, 2) relative to ``centre``; None without points."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(xy) == 0:
        return None
    mean = xy.mean(axis=0)
    return float(mean[0] - centre[0]), float(mean[1] - centre[1])


def principal_axes(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Centroid, eigenvalues (ascending) and unit eigenvectors (columns) of the covariance
    of the points ``xy`` (n, 2): the PCA of a particle configuration (the paper's Fig. 6);
    None with fewer than two points."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(xy) < 2:
        return None
    eigenvalues, vectors = np.linalg.eigh(np.cov(xy, rowvar=False, bias=True))
    return xy.mean(axis=0), np.maximum(eigenvalues, 0.0), vectors


def spread_area(xy: np.ndarray) -> float | None:
    """The area [m^2] the points ``xy`` (n, 2) cover, from their covariance: ``4 pi
    sqrt(det C)``, the area of a uniform disc or ellipse of the same second moments (a disc
    of radius r has C = r^2 / 4 I); robust to a few strays, unlike a hull. None with fewer
    than two points."""
    axes = principal_axes(xy)
    if axes is None:
        return None
    return float(4 * np.pi * np.sqrt(np.prod(axes[1])))


def roundness(xy: np.ndarray) -> float | None:
    """Second over first eigenvalue of the covariance of the points ``xy`` (n, 2): 1 for a
    round patch, 0 for a line; None with fewer than two points."""
    axes = principal_axes(xy)
    if axes is None:
        return None
    _, eigenvalues, _ = axes
    if eigenvalues[-1] <= 0.0:   # all points at one place: no direction stands out
        return 1.0
    return float(eigenvalues[0] / eigenvalues[-1])
