"""The stage of a timeline that measures particle fluids in the monitoring samples
(:class:`Fluids`): the ``spill`` events and the pouring quantities, with the measures of
:mod:`projection_server.timeline.pouring`; of a batter whose heat is simulated, its
temperature, setting and the pancake that emerges from it (``set``, ``upside_down``), with
those of :mod:`projection_server.timeline.cooking`. Each is defined in the module doc of
:mod:`projection_server.timeline.translate`, the one list of them all.
"""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.timeline import cooking, pouring
from projection_server.timeline.intervals import intervals_from_samples

if TYPE_CHECKING:
    from projection_server.timeline.samples import Sample

__all__ = ['Fluids']


class Fluids:
    """Events and quantities of the particle fluids of a projection (none without fluids)."""

    def __init__(self, samples: list[Sample], scenario: Any):
        """``scenario``'s entities have a ``unit`` (their object class) whose
        ``fluid_role(entity)`` says what they are to a fluid: a ``fluid``, a ``surface``
        particles land on, a ``vessel`` that holds them or a ``level`` spilled on."""
        self.samples = [x for x in samples if x.particles]
        self.radius: dict[str, float] = {}
        self.makers: dict[str, pouring.Disc] = {}
        self.cups: dict[str, Any] = {}
        self._fluents: list[list[Any]] | None = None
        tables = []
        if not self.samples:
            return
        # What each entity is to a fluid, as its object class says (its fluid_role).
        for entity in scenario.entities:
            role = entity.unit.fluid_role
            kind, *values = role(entity) if role is not None else (None,)
            if kind == 'fluid':
                self.radius[entity.name] = values[0]
            elif kind == 'surface':
                self.makers[entity.name] = pouring.Disc(*values)
            elif kind == 'vessel':
                self.cups[entity.name] = tuple(values)
            elif kind == 'level':
                tables.append(values[0])
        floor = min((d.top for d in self.makers.values()), default=0.0)
        self.table_top = max(tables, default=floor)

    def _vessels(self, sample: Sample) -> dict[str, pouring.Vessel]:
        return {name: pouring.Vessel(*sample.poses[name], *inside)
                for name, inside in self.cups.items() if name in sample.poses}

    def fluents(self) -> list[list[Any]]:
        """The fluents ``set(F)`` and ``upside_down(F)`` of batters ``[name, args, start,
        end]``."""
        if self._fluents is not None:
            return self._fluents
        rows = []
        for fluid in self._batters():
            set_, upside_down = self._cooking(fluid)
            times = [x.t for x in self._batter_samples(fluid)]
            for name, values in (('set', set_), ('upside_down', upside_down)):
                rows += [[name, [fluid], start, end]
                         for start, end in intervals_from_samples(times, values)]
        self._fluents = rows
        return rows

    def _batters(self) -> list[str]:
        """The fluids whose heat was logged."""
        return sorted({fluid for x in self.samples for fluid in x.batter})

    def _batter_samples(self, fluid: str) -> list[Sample]:
        return [x for x in self.samples if fluid in x.batter and fluid in x.particles]

    def _cooking(self, fluid: str) -> tuple[list[bool], list[bool]]:
        """Per sample of ``fluid``: whether it is set, and whether the pancake that emerged
        from it (its largest bonded cluster, of at least ``MIN_CLUSTER`` of its particles)
        lies upside down, turned from where its particles set."""
        set_, upside_down = [], []
        reference = None   # each particle's position where it was first seen set
        known = None
        cluster, bonds = None, None
        for sample in self._batter_samples(fluid):
            positions = sample.particles[fluid]
            flags = sample.batter[fluid][1]
            if reference is None:
                reference = positions.copy()
                known = flags.copy()
            new = flags & ~known
            reference[new] = positions[new]
            known |= flags
            set_.append(bool(flags.mean() >= cooking.SET_FRACTION) if len(flags) else False)
            pairs = sample.bonds.get(fluid, np.zeros((0, 2), dtype=np.int64))
            if pairs is not bonds:   # the same bonds (the same array) until they change
                bonds = pairs
                cluster = cooking.largest_cluster(pairs, len(positions))
                if len(cluster) < max(3, cooking.MIN_CLUSTER * len(positions)):
                    cluster = None
            upside_down.append(cluster is not None and cooking.upside_down(
                cooking.rotation(reference[cluster], positions[cluster])))
        return set_, upside_down

    def events(self) -> list[list[Any]]:
        """The ``spill`` events, and a batter's ``set`` and ``flip`` events, ``[name, args,
        start, end]``."""
        events = [[{'set': 'set', 'upside_down': 'flip'}[name], args, start, start]
                  for name, args, start, _ in self.fluents()]
        for fluid, radius in self.radius.items():
            level = self.table_top + 2 * radius
            for sample in self.samples:
                positions = sample.particles.get(fluid)
                if positions is not None and pouring.reached_level(positions, level).any():
                    events.append(['spill', [fluid], sample.t, sample.t])
                    break
        return events

    @staticmethod
    def _batter_on(maker: str, masks: list[tuple[str, np.ndarray]], last: Sample
                   ) -> list[list[Any]]:
        """The temperatures and bonds of the batter on ``maker`` (the particles of each
        fluid in ``masks``), in the order of ``particles_on_positions``: the batter a next
        projection starts from. None unless every fluid on it has its heat logged."""
        if not masks or any(fluid not in last.batter for fluid, _ in masks):
            return []
        temperatures, bonds, offset = [], [], 0
        for fluid, mask in masks:
            index = np.full(len(mask), -1)
            index[mask] = offset + np.arange(int(mask.sum()))
            temperatures += [float(v) for v in last.batter[fluid][0][mask]]
            pairs = index[last.bonds.get(fluid, np.zeros((0, 2), dtype=np.int64))]
            bonds += [[int(i), int(j)] for i, j in pairs if i >= 0 and j >= 0]
            offset += int(mask.sum())
        return [['particles_on_temperatures', [maker], temperatures],
                ['particles_on_bonds', [maker], bonds]]

    def quantities(self) -> list[list[Any]]:
        """The quantities ``[name, args, value]`` of the fluids at the last sample."""
        if not self.samples:
            return []
        last = self.samples[-1]
        vessels = self._vessels(last)
        on = {name: [] for name in self.makers}
        masks: dict[str, list[tuple[str, np.ndarray]]] = {name: [] for name in self.makers}
        inside = {name: 0 for name in vessels}
        rows: list[list[Any]] = []
        for fluid, radius in self.radius.items():
            positions = last.particles.get(fluid, np.zeros((0, 3)))
            placed = np.zeros(len(positions), dtype=bool)
            # Vessels first: the bottom of a cup held low over a maker is within the pile
            # height above it, and what is in the cup is not on the maker.
            for name, vessel in vessels.items():
                mask = pouring.in_vessel(positions, vessel, radius) & ~placed
                inside[name] += int(mask.sum())
                placed |= mask
            for name, disc in self.makers.items():
                mask = pouring.on_disc(positions, disc, radius) & ~placed
                on[name].append(positions[mask])
                masks[name].append((fluid, mask))
                placed |= mask
            rows.append(['particles_spilled', [fluid], int((~placed).sum())])
        for name, disc in self.makers.items():
            points = np.concatenate(on[name]) if on[name] else np.zeros((0, 3))
            xy = points[:, :2]
            rows.append(['particles_on', [name], len(xy)])
            rows.append(['particles_on_positions', [name],
                         [[float(v) for v in point] for point in points]])
            offset = pouring.centroid_offset(xy, disc.centre)
            if offset is not None:
                rows.append(['centroid_offset_x', [name], offset[0]])
                rows.append(['centroid_offset_y', [name], offset[1]])
            round_ = pouring.roundness(xy)
            if round_ is not None:
                rows.append(['roundness', [name], round_])
                rows.append(['spread_area', [name], pouring.spread_area(xy)])
            rows += self._batter_on(name, masks[name], last)
        rows += [['particles_in', [name], count] for name, count in sorted(inside.items())]
        for fluid in self._batters():
            sample = self._batter_samples(fluid)[-1]
            temperatures, flags = sample.batter[fluid]
            bonds = sample.bonds.get(fluid, np.zeros((0, 2), dtype=np.int64))
            rows += [['temperature', [fluid], float(temperatures.mean())],
                     ['set_fraction', [fluid], float(flags.mean())],
                     ['particle_temperatures', [fluid], [float(v) for v in temperatures]],
                     ['particle_positions', [fluid],
                      [[float(v) for v in point] for point in sample.particles[fluid]]],
                     ['bonds', [fluid], [[int(i), int(j)] for i, j in bonds]]]
        return rows
