"""Translation of a projection's records into a timeline of fluents, events and quantities.

``translate_records(records, bag, scenario)`` returns the dict of ``docs/contracts.md``,
from what the monitor logged (:class:`~projection_server.bags.Record` s, the worker's own
or read back from a bag: :func:`projection_server.workers.run.translate_bag`) and the
projection's checked scenario. Every monitoring sample
(one ``ContactArray``, ``/tf``, ``GripperState`` and ``ObjectStateArray`` per step) gives a
truth value of each fluent; fluents hold on maximal intervals of true samples, with gaps
shorter than ``timeline.gap_merge`` merged; events are read off those intervals. The
thresholds are the ``timeline`` settings recorded in the bag itself.

Fluents (arguments are entity names):

* ``contact(A, B)``: A and B touch with at least ``contact_force_min``; A < B by name.
* ``supported_by(A, B)``: A touches B (not a gripper) and the contact normal, from B to A,
  is within ``support_max_angle`` of straight up.
* ``in_gripper(O)``: O touches every finger link of a gripper.
* ``on(O, S)``: O is supported by S and not in a gripper (it rests on S).
* ``broken(O)``: O's object model reports it broken. An interval of a state fluent of O
  (``broken``, ``upside_down``) that spans the end of a ``drop(O)`` is reported as two:
  up to the drop's end, and from the next sample (a state O lands in holds after the drop).
* ``upside_down(P)``: the plane fitted to the logged segment frames of deformable body P
  (``P`` and its links ``P/...``; a pancake) has its upper side's normal pointing down (see
  :mod:`projection_server.timeline.turning`).

Events (``[name, args, start, end]``, points have start = end):

* ``grasp(O)``: an ``in_gripper(O)`` interval begins.
* ``release(O)``: it ends while its gripper's command is ``open``.
* ``lift(O)``: a ``supported_by(O, S)`` interval ends while O is in the gripper.
* ``slip(O)``: O is lost from the grasp: it leaves the gripper while the command is not
  ``open`` (a point at the grasp's end), or it is held to the end of the grasp sunk more
  than ``slip_distance`` below where the gripper carried it (it slides out between the
  fingers and ends below the lift's height; the event spans from the last sample sunk less
  than a fifth of that to the sample that exceeds it). Motion is measured relative to the
  gripper's fingers from ``grasp_settle`` after the grasp, while O is not broken.
* ``shift(O)``: O moves within the grasp and is not lost: while held and not broken it
  moves by more than ``slip_distance`` or turns by more than ``slip_angle`` relative to the
  fingers (from the last sample within a fifth of the threshold to the sample that crosses
  it), and no ``slip(O)`` ends that grasp.
* ``break(O)``: ``broken(O)`` begins.
* ``flip(P)``: ``upside_down(P)`` begins.
* ``drop(O)``: O touches nothing for at least ``drop_min_duration`` and falls meanwhile;
  the event spans that time.

* ``spill(F)``: a particle of fluid F first reaches the table (its centre within two
  particle radii of the table's top, or lower).

Quantities: ``max_load(O)`` [N] and ``load_limit(O)`` [N] of modelled objects,
``lift_height(O)`` [m] (highest minus initial height) of every moving body. Of particle
fluids (at the last sample, see :mod:`projection_server.timeline.pouring`):
``particles_on(M)`` per pancake maker M, ``particles_in(C)`` per cup C,
``particles_spilled(F)`` (neither in a cup nor on a maker) per fluid F,
``particles_on_positions(M)``, the world positions ``[X, Y, Z]`` [m] of the particles on M
(what ``object_model(pancake, _{particles: Points}, E)`` builds a pancake from), and of the
particles
on M ``centroid_offset_x(M)``, ``centroid_offset_y(M)`` [m] (world axes, relative to M's
centre; left out without particles) and ``roundness(M)`` (left out below two particles).
The fluent ``on(F, M)`` comes from the contacts, like every ``on``.
"""

from __future__ import annotations

from collections import defaultdict
import json
import math
import os
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.bags.schema import REFERENCE_LINKS
from projection_server.settings import TimelineSettings
from projection_server.timeline import pouring, turning
from projection_server.timeline.intervals import fluent_intervals, holds_at, Interval
from projection_server.timeline.samples import Samples

if TYPE_CHECKING:
    from collections.abc import Iterable

    from projection_server.bags.schema import Record
    from projection_server.timeline.samples import Sample

__all__ = ['translate_records']


def translate_records(records: Iterable[Record], bag: str | os.PathLike[str],
                      scenario: Any) -> dict[str, Any]:
    """The timeline of a projection from what its monitor logged, as plain
    :class:`~projection_server.bags.Record` s (a worker's own projection: the same
    timeline as its bag's); ``bag`` is the bag's path, ``scenario`` the projection's
    checked scenario (its ``entities``, each with ``name``, ``cls``, ``pose`` and
    ``properties``).

    Raises:
        ProjectionError: kind ``bag_error`` if the records are not a projection's.
    """
    samples = Samples()
    for record in records:
        samples.add(*record)
    info, samples_ = samples.finish(bag)
    settings_json = json.loads(info.settings_json)
    timeline = _Timeline(samples_, TimelineSettings(**settings_json['timeline']))
    fluids = _Fluids(samples_, scenario)
    return {
        'fluents': timeline.fluents(),
        'events': _sorted_events(timeline.events() + fluids.events()),
        'quantities': [[name, args, _plain(value)] for name, args, value
                       in timeline.quantities() + fluids.quantities()],
        'meta': {
            'bag': os.fspath(bag), 'scenario': info.scenario_name, 'program': info.program,
            'params': json.loads(info.parameters_json), 'job_key': info.job_key,
            'code_version': info.code_version,
            'duration': samples_[-1].t if samples_ else 0.0, 'samples': len(samples_),
            'timeline_settings': settings_json['timeline'],
        },
    }


def _plain(value: Any) -> Any:
    """Numbers as Python's own (in memory they may still be numpy scalars)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _sorted_events(events: list[list[Any]]) -> list[list[Any]]:
    unique = {(e[0], tuple(e[1]), e[2], e[3]) for e in events}
    return [[n, list(a), s, e] for n, a, s, e in sorted(unique, key=lambda r: (r[2], r[0],
                                                                              r[1]))]


def _upside_down(sample: Sample, body: str, references: list[str]) -> bool:
    """Whether the segments of ``body`` (its frame and link frames ``body/...``, with the
    reference links of :data:`~projection_server.bags.REFERENCE_LINKS`, whose
    frames are ``references``) are upside down; False for bodies without them."""
    a, b = (sample.poses.get(name) for name in references)
    if a is None or b is None or body not in sample.poses:
        return False
    positions = [pose[0] for name, pose in sample.poses.items()
                 if name == body or name.startswith(body + '/')]
    normal = turning.upper_normal(np.array(positions), sample.poses[body][0], a[0], b[0])
    return turning.is_upside_down(normal)


# Fluents of an object's state (not of its relations): an interval of one that spans the end
# of a drop of its object is reported as two, before and after the drop, so that a state
# the object is in when it lands holds after the drop (what section II's query asks).
_STATES = frozenset({'broken', 'upside_down'})


class _Timeline:
    """Fluents, events and quantities of a list of samples."""

    def __init__(self, samples: list[Sample], settings: TimelineSettings):
        self.samples = samples
        self.settings = settings
        self.times = [x.t for x in samples]
        self.end = self.times[-1] if self.times else 0.0
        self.grippers = sorted({g for x in samples for g in x.grippers})
        # Moving bodies: logged on /tf (static ones are on /tf_static), without link frames.
        self.bodies = sorted({name for x in samples for name in x.moving} - set(self.grippers))
        self._booleans: dict[tuple[str, tuple[str, ...]], list[bool]] = defaultdict(
            lambda: [False] * len(samples))
        self._sample_fluents()
        self._intervals = {key: fluent_intervals(self.times, values, self.settings.gap_merge)
                           for key, values in self._booleans.items()}
        for key, values in self._booleans.items():
            if key[0] == 'broken':   # monotone, and a break must not be merged away
                self._intervals[key] = fluent_intervals(self.times, values, 0.0)

    # --- fluents ------------------------------------------------------------------------
    def _sample_fluents(self) -> None:
        cos_support = math.cos(self.settings.support_max_angle)
        booleans = self._booleans
        supports: list[tuple[str, tuple[str, ...]]] = []   # the supported_by keys
        references = {body: [f'{body}/{link}' for link in REFERENCE_LINKS]
                      for body in self.bodies}
        for i, sample in enumerate(self.samples):
            touching: dict[str, set[tuple[str, str]]] = defaultdict(set)   # obj -> (body, link)
            held: set[str] = set()
            for body_a, link_a, body_b, link_b, force, normal_z in sample.contacts:
                if force < self.settings.contact_force_min or body_a == body_b:
                    continue
                self._booleans[('contact', tuple(sorted((body_a, body_b))))][i] = True
                touching[body_a].add((body_b, link_b))
                touching[body_b].add((body_a, link_a))
                for obj, support, up in ((body_a, body_b, normal_z),
                                         (body_b, body_a, -normal_z)):
                    if support not in self.grippers and up >= cos_support:
                        key = ('supported_by', (obj, support))
                        if key not in booleans:   # in the order they are first seen
                            supports.append(key)
                        booleans[key][i] = True
            for name, gripper in sample.grippers.items():
                fingers = {(name, link) for link in gripper.finger_links}
                for obj, links in touching.items():
                    if fingers and fingers <= links:
                        held.add(obj)
                        self._booleans[('in_gripper', (obj,))][i] = True
            for key in supports:
                if booleans[key][i] and key[1][0] not in held:
                    booleans[('on', key[1])][i] = True
            for name, state in sample.objects.items():
                if state.broken:
                    self._booleans[('broken', (name,))][i] = True
            for body in self.bodies:
                if _upside_down(sample, body, references[body]):
                    self._booleans[('upside_down', (body,))][i] = True

    def fluents(self) -> list[list[Any]]:
        rows = []
        drop_ends: dict[str, list[float]] | None = None
        for (name, args), intervals in self._intervals.items():
            for start, end in intervals:
                if name not in _STATES:
                    rows.append([name, list(args), start, end])
                    continue
                if drop_ends is None:
                    drop_ends = defaultdict(list)
                    for _, (obj,), _, drop_end in self._drops():
                        drop_ends[obj].append(drop_end)
                for piece in self._split(start, end, drop_ends[args[0]]):
                    rows.append([name, list(args), *piece])
        return sorted(rows, key=lambda r: (r[2], r[0], r[1]))

    def _split(self, start: float, end: float, cuts: list[float]) -> list[Interval]:
        """``start`` to ``end`` cut after each of ``cuts`` inside it: the pieces meet at
        consecutive samples."""
        pieces = []
        for cut in sorted(cuts):
            after = self._next_time(cut)
            if start <= cut < end and after is not None:
                pieces.append((start, cut))
                start = after
        return pieces + [(start, end)]

    def intervals(self, name: str, *args: str) -> list[Interval]:
        return self._intervals.get((name, args), [])

    # --- events -------------------------------------------------------------------------
    def events(self) -> list[list[Any]]:
        events: list[list[Any]] = []
        for (name, args), intervals in sorted(self._intervals.items()):
            obj = args[0]
            for start, end in intervals:
                if name == 'in_gripper':
                    events.append(['grasp', [obj], start, start])
                    events.extend(self._grip(obj, start, end))
                    if end < self.end and self._command_after(end) == 'open':
                        events.append(['release', [obj], end, end])
                elif name == 'supported_by':
                    if end < self.end and holds_at(self.intervals('in_gripper', obj), end):
                        events.append(['lift', [obj], end, end])
                elif name == 'broken':
                    events.append(['break', [obj], start, start])
                elif name == 'upside_down':
                    events.append(['flip', [obj], start, start])
        events.extend(self._drops())
        return _sorted_events(events)

    def _grip(self, obj: str, start: float, end: float) -> list[list[Any]]:
        """The ``shift`` or ``slip`` of ``obj`` in its grasp from ``start`` to ``end``."""
        limit = self.settings.slip_distance
        reference = None
        onset = sink_onset = start
        shift = sunk = None
        sink = 0.0
        for sample in self.samples:
            if sample.t < start or sample.t > end or self._broken_at(obj, sample.t):
                continue
            relative = self._relative_pose(obj, sample)
            if relative is None:
                continue
            if reference is None:
                if sample.t >= min(start + self.settings.grasp_settle, end):
                    reference = relative
                    onset = sink_onset = sample.t
                continue
            moved = relative[0] - reference[0]
            cos_angle = (np.trace(reference[1].T @ relative[1]) - 1.0) / 2.0
            angle = math.acos(min(1.0, max(-1.0, cos_angle)))
            # Relative to the thresholds: 1 means moved; below 1/5 the grip still holds.
            ratio = max(float(np.linalg.norm(moved)) / limit, angle / self.settings.slip_angle)
            if shift is None:
                if ratio > 1.0:
                    shift = ['shift', [obj], onset, sample.t]
                elif ratio <= 0.2:
                    onset = sample.t
            sink = -float((relative[2] @ moved)[2])   # downwards in the world
            if sunk is None:
                if sink > limit:
                    sunk = (sink_onset, sample.t)
                elif sink <= 0.2 * limit:
                    sink_onset = sample.t
        after = self._next_time(end)
        if after is not None and self._command_after(end) != 'open' \
                and not self._broken_at(obj, after):
            return [['slip', [obj], end, end]]
        if sunk is not None and sink > limit:
            return [['slip', [obj], *sunk]]
        return [shift] if shift is not None else []

    def _drops(self) -> list[list[Any]]:
        events = []
        for obj in self.bodies:
            contacts = [iv for (name, args), ivs in self._intervals.items()
                        if name == 'contact' and obj in args for iv in ivs]
            free = [not holds_at(contacts, t) for t in self.times]
            for start, end in fluent_intervals(self.times, free, 0.0):
                if end - start < self.settings.drop_min_duration:
                    continue
                if self._height(obj, end) < self._height(obj, start):
                    events.append(['drop', [obj], start, end])
        return events

    # --- quantities ---------------------------------------------------------------------
    def quantities(self) -> list[list[Any]]:
        rows: list[list[Any]] = []
        loads: dict[str, float] = {}
        limits: dict[str, float] = {}
        for sample in self.samples:
            for name, state in sample.objects.items():
                loads[name] = max(loads.get(name, 0.0), state.load)
                if state.load_limit > 0:
                    limits[name] = state.load_limit
        rows += [['max_load', [name], value] for name, value in sorted(loads.items())]
        rows += [['load_limit', [name], value] for name, value in sorted(limits.items())]
        for obj in self.bodies:
            heights = [float(x.poses[obj][0][2]) for x in self.samples if obj in x.poses]
            rows.append(['lift_height', [obj], max(heights) - heights[0]])
        return rows

    # --- helpers ------------------------------------------------------------------------
    def _next_time(self, time: float) -> float | None:
        """The first sample time after ``time``, None at the end."""
        return next((t for t in self.times if t > time), None)

    def _command_after(self, time: float) -> str:
        for sample in self.samples:
            if sample.t > time and sample.grippers:
                return next(iter(sample.grippers.values())).command
        return ''

    def _broken_at(self, obj: str, time: float) -> bool:
        return holds_at(self.intervals('broken', obj), time)

    def _height(self, obj: str, time: float) -> float:
        for sample in self.samples:
            if sample.t >= time and obj in sample.poses:
                return float(sample.poses[obj][0][2])
        return math.nan

    def _relative_pose(self, obj: str, sample: Sample
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Pose of ``obj`` in the frame between the fingers of the gripper holding it, and
        that frame's rotation in the world."""
        for name, gripper in sample.grippers.items():
            frames = [sample.poses.get(f'{name}/{link}') for link in gripper.finger_links]
            if obj not in sample.poses or not frames or any(f is None for f in frames):
                continue
            origin = sum(f[0] for f in frames) / len(frames)
            rot = frames[0][1]
            position, orientation = sample.poses[obj]
            return rot.T @ (position - origin), rot.T @ orientation, rot
        return None


class _Fluids:
    """Events and quantities of the particle fluids of a projection (none without fluids)."""

    def __init__(self, samples: list[Sample], scenario: Any):
        self.samples = [x for x in samples if x.particles]
        self.radius: dict[str, float] = {}
        self.makers: dict[str, pouring.Disc] = {}
        self.cups: dict[str, Any] = {}
        tables = []
        if not self.samples:
            return
        for entity in scenario.entities:
            p, (x, y, z) = entity.properties, entity.pose.xyz
            if entity.cls == 'particle_fluid':
                self.radius[entity.name] = p['particle_radius']
            elif entity.cls == 'pancake_maker':
                self.makers[entity.name] = pouring.Disc((x, y), z + p['height'] / 2,
                                                        p['radius'])
            elif entity.cls == 'cup':
                wall = p['wall_thickness']
                self.cups[entity.name] = (p['radius'] - wall, -p['height'] / 2 + wall,
                                          p['height'] / 2)
            elif entity.cls == 'table':
                tables.append(p.get('height', z))
        floor = min((d.top for d in self.makers.values()), default=0.0)
        self.table_top = max(tables, default=floor)

    def _vessels(self, sample: Sample) -> dict[str, pouring.Vessel]:
        return {name: pouring.Vessel(*sample.poses[name], *inside)
                for name, inside in self.cups.items() if name in sample.poses}

    def events(self) -> list[list[Any]]:
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
        rows += [['particles_in', [name], count] for name, count in sorted(inside.items())]
        return rows
