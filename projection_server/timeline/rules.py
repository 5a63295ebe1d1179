"""The stage of a timeline that reads the fluents, events and quantities of bodies off the
monitoring samples (:class:`Rules`): contacts, support, grasps, breaks and flips, drops,
tipping over, robots' collisions, loads, lift heights, displacements and final poses. Each
is defined in the module doc of :mod:`projection_server.timeline.translate`, the one list
of them all.
"""

from __future__ import annotations

import bisect
from collections import defaultdict
import functools
import math
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.bags.schema import REFERENCE_LINKS
from projection_server.timeline import turning
from projection_server.timeline.intervals import (fluent_intervals, holds_at,
                                                  intervals_from_samples)

if TYPE_CHECKING:
    from projection_server.settings import TimelineSettings
    from projection_server.timeline.intervals import Interval
    from projection_server.timeline.samples import Sample

__all__ = ['Rules', 'sorted_events']

# Fluents of an object's state (not of its relations): an interval of one that spans the end
# of a drop of its object is reported as two, before and after the drop, so that a state
# the object is in when it lands holds after the drop (what section II's query asks).
# How short the mean of the fingers' contact normals is for them to hold what they touch
# (fingers that touch it side by side, pushing, do not).
OPPOSED = 0.5

_STATES = frozenset({'broken', 'upside_down'})


def sorted_events(events: list[list[Any]]) -> list[list[Any]]:
    """Each of ``events`` once, by start, name and arguments."""
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
    # Only the body's own frames are composed (a robot's link chain need not be).
    prefix = body + '/'
    positions = [sample.poses[name][0] for name in sample.poses.names()
                 if name == body or name.startswith(prefix)]
    normal = turning.upper_normal(np.array(positions), sample.poses[body][0], a[0], b[0])
    return turning.is_upside_down(normal)


def _overlaps(intervals: list[Interval], start: float, end: float) -> bool:
    """Whether one of ``intervals`` meets the closed interval from ``start`` to ``end``."""
    return any(s <= end and start <= e for s, e in intervals)


class Rules:
    """Fluents, events and quantities of a list of samples."""

    def __init__(self, samples: list[Sample], settings: TimelineSettings):
        self.samples = samples
        self.settings = settings
        self.times = [x.t for x in samples]
        self.end = self.times[-1] if self.times else 0.0
        self.grippers = sorted({g for x in samples for g in x.grippers})
        self.robots = sorted({r for x in samples for r in x.robots} | set(self.grippers))
        # Moving bodies: logged on /tf (static ones are on /tf_static), without link frames,
        # and not robots.
        self.bodies = sorted({name for x in samples for name in x.moving} - set(self.robots))
        falses = functools.partial(list, [False] * len(samples))
        self._booleans: dict[tuple[str, tuple[str, ...]], list[bool]] = defaultdict(falses)
        # Per sample, unmerged: whether a body touches anything (drops); whether a robot's
        # links but its base touch an object, and whether its gripper holds it (collisions).
        self._touching: dict[str, list[bool]] = defaultdict(falses)
        self._robot_touching: dict[tuple[str, str], list[bool]] = defaultdict(falses)
        self._held: dict[tuple[str, str], list[bool]] = defaultdict(falses)
        self._sample_fluents()
        self._intervals = {key: fluent_intervals(self.times, values, self.settings.gap_merge)
                           for key, values in self._booleans.items()}
        for key, values in self._booleans.items():
            if key[0] == 'broken':   # monotone, and a break must not be merged away
                self._intervals[key] = fluent_intervals(self.times, values, 0.0)

    # --- fluents ------------------------------------------------------------------------
    def _sample_fluents(self) -> None:
        cos_support = math.cos(self.settings.support_max_angle)
        force_min = self.settings.contact_force_min
        booleans = self._booleans
        any_touching, robot_touching, gripper_held = (self._touching, self._robot_touching,
                                                      self._held)
        grippers = set(self.grippers)
        supports: list[tuple[str, tuple[str, ...]]] = []   # the supported_by keys
        references = {body: [f'{body}/{link}' for link in REFERENCE_LINKS]
                      for body in self.bodies}
        robots = set(self.robots)
        # A gripper's finger links, as the (body, link) pairs a contact names.
        fingers_of: dict[tuple[str, tuple[str, ...]], set[tuple[str, str]]] = {}
        for i, sample in enumerate(self.samples):
            touching: dict[str, set[tuple[str, str]]] = defaultdict(set)   # obj -> (body, link)
            # obj -> {(body, link): the contact normal, pointing from that link into obj}
            normals: dict[str, dict[tuple[str, str], Any]] = defaultdict(dict)
            held: set[str] = set()
            for body_a, link_a, body_b, link_b, force, normal in sample.contacts:
                if force < force_min or body_a == body_b:
                    continue
                normal_z = normal[2]
                booleans[('contact', (body_a, body_b) if body_a <= body_b
                          else (body_b, body_a))][i] = True
                touching[body_a].add((body_b, link_b))
                touching[body_b].add((body_a, link_a))
                normals[body_a][(body_b, link_b)] = normal
                normals[body_b][(body_a, link_a)] = (-normal[0], -normal[1], -normal[2])
                any_touching[body_a][i] = any_touching[body_b][i] = True
                # the base ('') may rest on its mount
                if link_a and body_a in robots:
                    robot_touching[(body_a, body_b)][i] = True
                if link_b and body_b in robots:
                    robot_touching[(body_b, body_a)][i] = True
                if body_b not in grippers and normal_z >= cos_support:
                    key = ('supported_by', (body_a, body_b))
                    if key not in booleans:   # in the order they are first seen
                        supports.append(key)
                    booleans[key][i] = True
                if body_a not in grippers and -normal_z >= cos_support:
                    key = ('supported_by', (body_b, body_a))
                    if key not in booleans:
                        supports.append(key)
                    booleans[key][i] = True
            for name, gripper in sample.grippers.items():
                links = tuple(gripper.finger_links)
                fingers = fingers_of.get((name, links))
                if fingers is None:
                    fingers = fingers_of[(name, links)] = {(name, link) for link in links}
                for obj, touched in touching.items():
                    if fingers and fingers <= touched and _opposed(
                            [normals[obj][f] for f in fingers]):
                        held.add(obj)
                        booleans[('in_gripper', (obj,))][i] = True
                        gripper_held[(name, obj)][i] = True
            for key in supports:
                if booleans[key][i] and key[1][0] not in held:
                    booleans[('on', key[1])][i] = True
            for name, state in sample.objects.items():
                if state.broken:
                    booleans[('broken', (name,))][i] = True
            for body in self.bodies:
                if _upside_down(sample, body, references[body]):
                    booleans[('upside_down', (body,))][i] = True

    def fluents(self) -> list[list[Any]]:
        """The fluents' intervals ``[name, args, start, end]``, by start, name and args."""
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
        """The intervals of fluent ``name(args)`` (a state's not split at drops)."""
        return self._intervals.get((name, args), [])

    # --- events -------------------------------------------------------------------------
    def events(self) -> list[list[Any]]:
        """The events ``[name, args, start, end]``, each once, by start, name and args."""
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
        events.extend(self._tips())
        events.extend(self._collisions())
        return sorted_events(events)

    def _grip(self, obj: str, start: float, end: float) -> list[list[Any]]:
        """The ``shift`` or ``slip`` of ``obj`` in its grasp from ``start`` to ``end``."""
        limit = self.settings.slip_distance
        onset = sink_onset = start
        shift = sunk = None
        sink = 0.0
        broken = self.intervals('broken', obj)
        # The motion is measured from the first sample held and not broken once the grip
        # has settled (the reference), to each such sample after it.
        settled = min(start + self.settings.grasp_settle, end)
        first, last = bisect.bisect_left(self.times, start), bisect.bisect_right(self.times, end)
        times, grips = [], []
        for sample in self.samples[first:last]:
            if sample.t < settled or broken and holds_at(broken, sample.t):
                continue
            grip = self._fingers_pose(obj, sample)
            if grip is not None:
                times.append(sample.t)
                grips.append(grip)
        if grips:
            onset = sink_onset = times[0]
        if len(grips) > 1:
            # Each sample's pose relative to the fingers, for all at once: numpy's matrix
            # products of a stack are those of each matrix, so the numbers are those of one
            # sample at a time.
            rotations = np.array([grip[0] for grip in grips])
            inverses = rotations.transpose(0, 2, 1)
            offsets = np.array([grip[1] for grip in grips])
            positions = np.matmul(inverses, offsets[:, :, None])[:, :, 0]
            turned = np.matmul(inverses, np.array([grip[2] for grip in grips]))
            moves = positions[1:] - positions[0]
            products = np.matmul(turned[0].T[None], turned[1:])
            sinks = (-np.matmul(rotations[1:], moves[:, :, None])[:, 2, 0]).tolist()
            for t, moved, product, sink in zip(times[1:], moves, products, sinks):
                cos_angle = (product.trace() - 1.0) / 2.0
                angle = math.acos(min(1.0, max(-1.0, cos_angle)))
                # Relative to the thresholds: 1 means moved; below 1/5 the grip still
                # holds. The length is np.linalg.norm's own: the sqrt of the dot product.
                ratio = max(math.sqrt(moved.dot(moved)) / limit,
                            angle / self.settings.slip_angle)
                if shift is None:
                    if ratio > 1.0:
                        shift = ['shift', [obj], onset, t]
                    elif ratio <= 0.2:
                        onset = t
                if sunk is None:   # downwards in the world
                    if sink > limit:
                        sunk = (sink_onset, t)
                    elif sink <= 0.2 * limit:
                        sink_onset = t
        after = self._next_time(end)
        if after is not None and self._command_after(end) != 'open' \
                and not self._broken_at(obj, after):
            return [['slip', [obj], end, end]]
        if sunk is not None and sink > limit:
            return [['slip', [obj], *sunk]]
        return [shift] if shift is not None else []

    def _drops(self) -> list[list[Any]]:
        """Free falls: a run of samples in which O touches nothing (a sample's contacts are
        those of every physics step since the previous one), during which O sinks at least
        ``drop_min_fall`` below where it last touched something. That contact was within the
        period of the sample before the run: its height is the higher of that period's
        ends. The lowest height counts the sample it lands in."""
        events = []
        indices = range(len(self.samples))
        for obj in self.bodies:
            heights = [self._height_at(obj, sample) for sample in self.samples]
            touching = self._touching[obj]
            for i, j in intervals_from_samples(indices, [not x for x in touching]):
                before = [h for h in heights[max(0, i - 2):i] or heights[:1]
                          if not math.isnan(h)]
                # The lowest height until it lands, in the sample it lands in, if any.
                fallen = [h for h in heights[i:j + 2] if not math.isnan(h)]
                if before and fallen and \
                        max(before) - min(fallen) >= self.settings.drop_min_fall:
                    events.append(['drop', [obj], self.times[i], self.times[j]])
        return events

    def _tips(self) -> list[list[Any]]:
        """The first sample at which a body's z axis is more than ``tip_angle`` from its
        z axis at its first sample (once per body)."""
        events = []
        limit = math.cos(self.settings.tip_angle)
        for obj in self.bodies:
            up = None
            for sample in self.samples:
                pose = sample.poses.get(obj)
                if pose is None:
                    continue
                if up is None:
                    up = pose[1][:, 2]
                elif float(up @ pose[1][:, 2]) < limit:
                    events.append(['tipped_over', [obj], sample.t, sample.t])
                    break
        return events

    def _collisions(self) -> list[list[Any]]:
        """Robot R's links but its base touch O, while O is neither in R's gripper nor
        the target of R's task. Without R's task states, a contact during which O is in
        R's gripper at some time is the approach (or release) of a grasp, not a collision."""
        events = []
        gap = self.settings.gap_merge
        informed = {robot for sample in self.samples for robot in sample.tasks}
        for (robot, obj), touching in sorted(self._robot_touching.items()):
            if obj == robot:
                continue
            held = fluent_intervals(self.times, self._held[(robot, obj)], gap)
            colliding = []
            for touch, sample in zip(touching, self.samples):
                task = sample.tasks.get(robot)
                colliding.append(touch and not holds_at(held, sample.t)
                                 and not (task is not None and task.target == obj))
            contacts = fluent_intervals(self.times, touching, gap)
            for start, end in fluent_intervals(self.times, colliding, gap):
                if robot not in informed and any(
                        c_start <= start <= c_end and _overlaps(held, c_start, c_end)
                        for c_start, c_end in contacts):
                    continue   # the approach or release of a grasp
                events.append(['collision', [robot, obj], start, end])
        return events

    # --- quantities ---------------------------------------------------------------------
    def quantities(self) -> list[list[Any]]:
        """The quantities ``[name, args, value]``."""
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
            seen = [x for x in self.samples if obj in x.poses]
            xyz = np.array([x.poses[obj][0] for x in seen], dtype=float)
            rows.append(['lift_height', [obj], float(xyz[:, 2].max() - xyz[0, 2])])
            rows.append(['displacement', [obj], float(np.linalg.norm(xyz[-1] - xyz[0]))])
            if len(seen) > 1:
                dt = np.diff([x.t for x in seen])
                speed = np.linalg.norm(np.diff(xyz, axis=0), axis=1) / np.maximum(dt, 1e-12)
                rows.append(['max_speed', [obj], float(speed.max())])
            rows.append(['final_pose', [obj], [[float(v) for v in xyz[-1]],
                                               list(seen[-1].poses.quaternion(obj))]])
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

    @staticmethod
    def _height_at(obj: str, sample: Sample) -> float:
        pose = sample.poses.get(obj)
        return float(pose[0][2]) if pose is not None else math.nan

    def _fingers_pose(self, obj: str, sample: Sample
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The rotation of the frame between the fingers of the gripper holding ``obj``, the
        position of ``obj`` from that frame's origin and its rotation, in the world."""
        if obj not in sample.poses:
            return None
        for name, gripper in sample.grippers.items():
            frames = [sample.poses.get(frame) for frame in _finger_frames(name, gripper)]
            if not frames or None in frames:
                continue
            origin = sum(f[0] for f in frames) / len(frames)
            position, orientation = sample.poses[obj]
            return frames[0][1], position - origin, orientation
        return None


@functools.lru_cache(maxsize=64)
def _frame_names(name: str, links: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(f'{name}/{link}' for link in links)


def _finger_frames(name: str, gripper: Any) -> tuple[str, ...]:
    """The frames of the finger links of gripper ``name``."""
    return _frame_names(name, tuple(gripper.finger_links))


def _opposed(normals: list[Any]) -> bool:
    """Whether contact normals (one per finger, unit vectors) squeeze from opposite sides:
    their mean is short (two opposite fingers: about 0; fingers side by side pushing: 1)."""
    # The mean as np.mean makes it (the rows summed in order, then divided), in plain
    # floats. Its squared length differs from np.linalg.norm's (BLAS) by a few ulps at most:
    # only within a millionth of the threshold is numpy asked.
    n = len(normals)
    x = y = z = 0.0
    for normal in normals:
        x, y, z = x + float(normal[0]), y + float(normal[1]), z + float(normal[2])
    x, y, z = x / n, y / n, z / n
    squared = x * x + y * y + z * z
    if abs(squared - OPPOSED * OPPOSED) > 1e-6:
        return squared < OPPOSED * OPPOSED
    mean = np.mean(np.asarray(normals, dtype=float), axis=0)
    return float(np.linalg.norm(mean)) < OPPOSED
