"""Pairs of points closer than a cutoff, found in a uniform cell grid with numpy.

Each point's cell is ``floor(x / cutoff)``; a pair can only lie in the same cell or in one
of the 13 neighbouring cells of a half shell, so those are the only candidates whose
distances are measured. Cells are looked up by sorting the cells' keys once and searching
the sorted keys for each offset (``searchsorted``): no Python loop over points.
"""

from __future__ import annotations

from typing import TYPE_CHECKING
import weakref

import numpy as np

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics

__all__ = ['NeighbourList', 'NeighbourLists', 'fluid_neighbour_list', 'pairs']

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
    d = positions.take(j, axis=0) - positions.take(i, axis=0)
    close = np.einsum('ij,ij->i', d, d) < cutoff * cutoff
    i, j, d = i[close], j[close], d.compress(close, axis=0)
    swap = i > j
    i[swap], j[swap] = j[swap], i[swap].copy()
    np.negative(d, out=d, where=swap[:, None])
    return i, j, d


def _none() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    empty = np.zeros(0, dtype=np.int64)
    return empty, empty, np.zeros((0, 3))


class NeighbourLists:
    """Verlet lists of one set of points for several cutoffs with one ``skin``, sharing
    their rebuilds and their distances: the pairs closer than the largest cutoff + skin are
    found with :func:`pairs` only when some point has moved more than ``skin / 2`` since they
    were, and each step their distances are measured once, however many lists ask. A smaller
    cutoff's candidates are a subset of them, in the order :func:`pairs` gives its own: each
    list gives what a list of its own would, to the bit."""

    def __init__(self, skin: float):
        self.skin = skin
        self.rebuilds = 0
        self._cutoffs: list[float] = []
        self._origin: np.ndarray | None = None
        self._positions: np.ndarray | None = None   # those measured last (kept: compared by id)
        self._i = self._j = np.zeros(0, dtype=np.int64)
        self._d = np.zeros((0, 3))
        self._squares = np.zeros(0)
        self._subsets: dict[float, np.ndarray | None] = {}   # None: all the candidates

    def add(self, cutoff: float) -> None:
        """Keep the pairs closer than ``cutoff`` too (from the next rebuild on)."""
        if cutoff not in self._cutoffs:
            self._cutoffs.append(cutoff)
            self._origin = None

    def within(self, cutoff: float, positions: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`pairs` of ``positions`` within ``cutoff`` (one that was added)."""
        if positions is not self._positions:
            self._measure(positions)
        subset = self._subsets[cutoff]
        if subset is None:
            close = np.flatnonzero(self._squares < cutoff * cutoff)
        else:
            close = subset[self._squares[subset] < cutoff * cutoff]
        return self._i[close], self._j[close], self._d.take(close, axis=0)

    def _measure(self, positions: np.ndarray) -> None:
        origin = self._origin
        if (origin is None or origin.shape != positions.shape
                or np.einsum('ij,ij->i', moved := positions - origin, moved).max()
                > (self.skin / 2) ** 2):
            self._rebuild(positions)
        self._d = d = positions.take(self._j, axis=0) - positions.take(self._i, axis=0)
        self._squares = np.einsum('ij,ij->i', d, d)
        self._positions = positions

    def _rebuild(self, positions: np.ndarray) -> None:
        top = max(self._cutoffs)
        self._i, self._j, d = pairs(positions, top + self.skin)
        squares = np.einsum('ij,ij->i', d, d)
        self._subsets = {cutoff: None if cutoff == top
                         else self._in_order(positions, squares, cutoff + self.skin)
                         for cutoff in self._cutoffs}
        self._origin = positions.copy()
        self.rebuilds += 1

    def _in_order(self, positions: np.ndarray, squares: np.ndarray,
                  reach: float) -> np.ndarray:
        """The indices of the candidates that ``pairs(positions, reach)`` finds, in its
        order: by the point whose half shell of cells holds the other, that cell's offset,
        the other point."""
        near = np.flatnonzero(squares < reach * reach)
        i, j = self._i[near], self._j[near]
        cell = np.floor(positions / reach).astype(np.int64)
        offset = cell.take(j, axis=0) - cell.take(i, axis=0)
        found = (np.abs(offset) <= 1).all(axis=1)
        near, i, j = near[found], i[found], j[found]
        code = (offset.compress(found, axis=0) + 1) @ _CODE
        forward = _FORWARD[code]
        finder, other = np.where(forward, i, j), np.where(forward, j, i)
        return near[np.lexsort((other, _SHELL_INDEX[code], finder))]


def _shell_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each cell offset (coded ``(offset + 1) @ code``): whether it is in the half shell
    (else its opposite is), and the index in the half shell of it or its opposite."""
    code = np.array([9, 3, 1], dtype=np.int64)
    index = {tuple(o): k for k, o in enumerate(_HALF_SHELL.tolist())}
    forward = np.zeros(27, dtype=bool)
    shell = np.zeros(27, dtype=np.int64)
    for c in range(27):
        o = (c // 9 - 1, c // 3 % 3 - 1, c % 3 - 1)
        forward[c] = o in index
        shell[c] = index[o] if o in index else index[tuple(-k for k in o)]
    return code, forward, shell


_CODE, _FORWARD, _SHELL_INDEX = _shell_tables()


class NeighbourList:
    """The pairs closer than ``cutoff``, step after step, from a Verlet list: the pairs
    closer than ``cutoff + skin`` are found with :func:`pairs` only when some point has
    moved more than ``skin / 2`` since they were; in between, only those candidates'
    distances are measured. Exact: no pair closer than ``cutoff`` is ever missed.

    With ``shared``, the list is drawn from those Verlet lists of the same points (and
    skin), with the same result."""

    def __init__(self, cutoff: float, skin: float, shared: NeighbourLists | None = None):
        if shared is None:
            shared = NeighbourLists(skin)
        elif shared.skin != skin:
            raise ValueError(f'a list of skin {skin} drawn from lists of skin {shared.skin}')
        shared.add(cutoff)
        self.cutoff, self.skin = cutoff, skin
        self._shared = shared

    @property
    def rebuilds(self) -> int:
        """How often its candidates were found again."""
        return self._shared.rebuilds

    def __call__(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`pairs` of ``positions`` within the cutoff."""
        return self._shared.within(self.cutoff, positions)


# physics -> (fluid, skin) -> the Verlet lists of its particles that its step hooks share;
# weak, so that the lists go with the world they were made for.
_FLUID_LISTS: weakref.WeakKeyDictionary[Physics, dict[tuple[str, float], NeighbourLists]] = (
    weakref.WeakKeyDictionary())


def fluid_neighbour_list(physics: Physics, fluid: str, cutoff: float,
                         skin: float) -> NeighbourList:
    """A Verlet list of the pairs of ``fluid``'s particles in ``physics`` closer than
    ``cutoff``; the lists of one physics, fluid and skin share their rebuilds and their
    distances each step. Ask for them before the first step."""
    lists = _FLUID_LISTS.setdefault(physics, {})
    shared = lists.get((fluid, skin))
    if shared is None:
        shared = lists[(fluid, skin)] = NeighbourLists(skin)
    return NeighbourList(cutoff, skin, shared)
