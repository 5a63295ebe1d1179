"""The stage of a timeline that measures particle fluids in the monitoring samples
(:class:`Fluids`): the ``spill`` events and the pouring quantities, with the measures of
:mod:`projection_server.timeline.pouring`. Each is defined in the module doc of
:mod:`projection_server.timeline.translate`, the one list of them all.
"""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.timeline import pouring

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

    def events(self) -> list[list[Any]]:
        """The ``spill`` events ``[name, args, start, end]``."""
        events = []
        for fluid, radius in self.radius.items():
            level = self.table_top + 2 * radius
            for sample in self.samples:
                positions = sample.particles.get(fluid)
                if positions is not None and pouring.reached_level(positions, level).any():
                    events.append(['spill', [fluid], sample.t, sample.t])
                    break
        return events

    def quantities(self) -> list[list[Any]]:
        """The quantities ``[name, args, value]`` of the fluids at the last sample."""
        if not self.samples:
            return []
        last = self.samples[-1]
        vessels = self._vessels(last)
        on = {name: [] for name in self.makers}
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
        rows += [['particles_in', [name], count] for name, count in sorted(inside.items())]
        return rows
