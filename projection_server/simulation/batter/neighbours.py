"""Pairs of points closer than a cutoff, found in a uniform cell grid with numpy.

Each point's cell is ``floor(x / cutoff)``; a pair can only lie in the same cell or in one
of the 13 neighbouring cells of a half shell, so those are the only candidates whose
distances are measured. Cells are looked up by sorting the cells' keys once and searching
the sorted keys for each offset (``searchsorted``): no Python loop over points.
"""

from __future__ import annotations

import numpy as np

__all__ = ['NeighbourList', 'pairs']

# The cell itself and 13 of its 26 neighbours: every unordered pair of cells once.
_HALF_SHELL = np.array([(0, 0, 0)] + [
    (dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
    if (dx, dy, dz) > (0, 0, 0)], dtype=np.int64)


def pairs(positions: np.ndarray, cutoff: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(i, j, d)``: every pair ``i < j`` of rows of ``positions`` (n x 3) closer than
    ``cutoff``, and ``d = positions[j] - positions[i]``; in no particular order."""
    n = len(positions)
    if n < 2:
        return _none()
    # Cells start at 1 so that a neighbour's index (cell - 1 .. cell + 1) is never negative
    # or past the grid, and keys never alias.
    cell = np.floor(positions / cutoff).astype(np.int64)
    cell -= cell.min(axis=0) - 1
    dims = cell.max(axis=0) + 2
    strides = np.array([dims[1] * dims[2], dims[2], 1], dtype=np.int64)
    key = cell @ strides
    order = np.argsort(key, kind='stable')
    sorted_keys = key[order]
    # Every point against every offset at once: n x 14 cells to look up.
    target = (key[:, None] + _HALF_SHELL @ strides).ravel()
    lo = np.searchsorted(sorted_keys, target, 'left')
    counts = np.searchsorted(sorted_keys, target, 'right') - lo
    total = int(counts.sum())
    if total == 0:
        return _none()
    i = np.repeat(np.arange(n).repeat(len(_HALF_SHELL)), counts)
    j = order[np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(total)]
    # In its own cell (offset 0) each pair is found twice and each point with itself.
    own = np.repeat(np.tile(np.arange(len(_HALF_SHELL)) == 0, n), counts)
    keep = ~own | (i < j)
    i, j = i[keep], j[keep]
    d = positions[j] - positions[i]
    close = np.einsum('ij,ij->i', d, d) < cutoff * cutoff
    i, j, d = i[close], j[close], d[close]
    swap = i > j
    i[swap], j[swap] = j[swap], i[swap].copy()
    d[swap] = -d[swap]
    return i, j, d


def _none() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    empty = np.zeros(0, dtype=np.int64)
    return empty, empty, np.zeros((0, 3))


class NeighbourList:
    """The pairs closer than ``cutoff``, step after step, from a Verlet list: the pairs
    closer than ``cutoff + skin`` are found with :func:`pairs` only when some point has
    moved more than ``skin / 2`` since they were; in between, only those candidates'
    distances are measured. Exact: no pair closer than ``cutoff`` is ever missed."""

    def __init__(self, cutoff: float, skin: float):
        self.cutoff, self.skin = cutoff, skin
        self.rebuilds = 0
        self._origin: np.ndarray | None = None
        self._i = self._j = np.zeros(0, dtype=np.int64)

    def __call__(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`pairs` of ``positions`` within the cutoff."""
        origin = self._origin
        if (origin is None or origin.shape != positions.shape
                or np.einsum('ij,ij->i', moved := positions - origin, moved).max()
                > (self.skin / 2) ** 2):
            self._i, self._j, _ = pairs(positions, self.cutoff + self.skin)
            self._origin = positions.copy()
            self.rebuilds += 1
        i, j = self._i, self._j
        d = positions[j] - positions[i]
        close = np.einsum('ij,ij->i', d, d) < self.cutoff * self.cutoff
        return i[close], j[close], d[close]
