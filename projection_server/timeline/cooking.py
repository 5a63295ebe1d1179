"""Measures of a cooking batter (its heat, setting and the pancake that emerges), pure numpy.

A batter is set when at least :data:`SET_FRACTION` of its particles are set. The pancake
that emerges is the largest cluster of particles joined by bonds (:func:`largest_cluster`),
of at least :data:`MIN_CLUSTER` of the batter's particles. Its orientation is the rotation
that carries its particles from where each of them set to where they are now (the Kabsch
rotation, :func:`rotation`): it lies upside down when that rotation turns the up axis at
least 60 deg below level (``turning.UPSIDE_DOWN_MAX_Z``, as the jointed pancake)::

    >>> cluster = largest_cluster(bonds, len(positions))
    >>> upside_down(rotation(set_positions[cluster], positions[cluster]))
"""

from __future__ import annotations

import numpy as np

from projection_server.timeline.turning import UPSIDE_DOWN_MAX_Z

__all__ = ['MIN_CLUSTER', 'SET_FRACTION', 'largest_cluster', 'rotation', 'upside_down']

SET_FRACTION = 0.5   # a batter is set while at least this fraction of its particles is
MIN_CLUSTER = 0.1    # a pancake: a bonded cluster of at least this fraction of the particles


def largest_cluster(bonds: np.ndarray, count: int) -> np.ndarray:
    """Indices (sorted) of the largest connected set of the ``count`` particles joined by
    ``bonds`` (index pairs, (m, 2)); empty without bonds. Ties: the one with the smallest
    index."""
    bonds = np.asarray(bonds, dtype=np.int64).reshape(-1, 2)
    if not len(bonds):
        return np.zeros(0, dtype=np.int64)
    label = np.arange(count)
    while True:   # each particle takes the smallest label of its bonded neighbours
        new = label.copy()
        np.minimum.at(new, bonds[:, 0], label[bonds[:, 1]])
        np.minimum.at(new, bonds[:, 1], label[bonds[:, 0]])
        new = new[new]
        if np.array_equal(new, label):
            break
        label = new
    bonded = np.zeros(count, dtype=bool)
    bonded[bonds.ravel()] = True
    sizes = np.bincount(label[bonded], minlength=count)
    return np.flatnonzero(label == int(np.argmax(sizes)))


def rotation(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """The proper rotation (3 x 3) that best carries the points ``before`` (n, 3) onto
    ``after`` (n, 3) about their centroids (Kabsch 1976; least squares)."""
    a = np.asarray(before, dtype=float) - np.mean(before, axis=0)
    b = np.asarray(after, dtype=float) - np.mean(after, axis=0)
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T


def upside_down(r: np.ndarray) -> bool:
    """Whether a body turned by ``r`` from lying flat lies upside down: its up axis, turned,
    points at least 60 deg below level."""
    return bool(r[2, 2] <= UPSIDE_DOWN_MAX_Z)
