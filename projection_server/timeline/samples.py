"""The first stage of a timeline: a projection's records as monitoring samples.

:class:`Samples` collects the :class:`~projection_server.bags.Record` s one at a time and
gives one :class:`Sample` per monitoring step: the world poses of its frames
(:class:`Poses`), the moving bodies and robots, the contacts, the grippers', object models'
and tasks' states and the particles' positions. The samples' poses are composed for all
samples whose tf message has the same frames at once (the same numbers as one sample at a
time). What the later stages read off the samples is listed in
:mod:`projection_server.timeline.translate`.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from itertools import chain
from typing import Any, NamedTuple, TYPE_CHECKING

import numpy as np

from projection_server.bags.schema import TfBlock
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.geometry import quaternion_of

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator
    import os

__all__ = ['Gripper', 'ObjectState', 'Poses', 'Sample', 'Samples', 'TaskState']


class Gripper(NamedTuple):
    """A gripper in one sample: its command and the links of its fingers."""

    command: str
    finger_links: list[str]


class ObjectState(NamedTuple):
    """An object model in one sample: its load [N], its load limit [N], whether it is
    broken."""

    load: float
    load_limit: float
    broken: bool


class TaskState(NamedTuple):
    """A robot's task in one sample: the plan step under way (-1: not a plan), its action
    (or the program's phase) and its target entity (``''``: none)."""

    step: int
    action: str
    target: str


@dataclass(slots=True)
class Sample:
    """What one monitoring step logged. ``robots`` are the driven bodies: those whose link
    frames are logged under their own frame (the monitor's chain of a robot's links), or
    that have a gripper or a task state."""

    t: float
    poses: Poses = field(default_factory=lambda: Poses())
    moving: set[str] = field(default_factory=set)
    robots: set[str] = field(default_factory=set)
    # (body_a, link_a, body_b, link_b, normal force, normal z)
    contacts: list[tuple[str, str, str, str, float, tuple[float, float, float]]] = field(
        default_factory=list)
    grippers: dict[str, Gripper] = field(default_factory=dict)
    objects: dict[str, ObjectState] = field(default_factory=dict)
    tasks: dict[str, TaskState] = field(default_factory=dict)   # robot -> its task's state
    particles: dict[str, np.ndarray] = field(default_factory=dict)   # fluid -> (n, 3)
    # fluid -> (temperatures (n,) [deg C], set flags (n,)), of fluids whose heat is simulated
    batter: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    bonds: dict[str, np.ndarray] = field(default_factory=dict)   # fluid -> pairs in force (m, 2)


# The kinds of records that make no sample of their own.
_SAMPLELESS = frozenset({'info', 'tf_static', 'particles', 'batter', 'bonds'})


class Samples:
    """Collects the monitoring samples of a projection, one record at a time."""

    def __init__(self) -> None:
        self.info: Any = None
        self.by_time: dict[int, Sample] = {}
        self.static: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.particles: dict[int, dict[str, np.ndarray]] = {}
        self.batter: dict[int, dict[str, tuple[np.ndarray, np.ndarray]]] = {}
        self.bonds: dict[int, dict[str, np.ndarray]] = {}

    def add(self, kind: str, t_ns: int, data: Any) -> None:
        """One record's ``kind``, time [ns] and ``data``."""
        if kind in _SAMPLELESS:
            if kind == 'info':
                self.info = data
            elif kind == 'tf_static':
                self.static.update(_poses(data))
            else:   # particles, batter, bonds: they make no sample of their own
                getattr(self, kind).setdefault(t_ns, {}).update(data)
            return
        if kind == 'tf_block':
            self._add_block(data)
            return
        sample = self.by_time.get(t_ns)
        if sample is None:
            sample = self.by_time[t_ns] = Sample(t_ns / 1e9)
        if kind == 'tf':
            sample.poses.add(data)
            moving, robots = _bodies_of([(parent, child) for parent, child, _, _ in data])
            sample.moving |= moving
            sample.robots |= robots
        elif kind == 'contacts':
            sample.contacts = data
        elif kind == 'gripper':
            name, command, finger_links = data
            sample.grippers[name] = Gripper(command, finger_links)
            sample.robots.add(name)
        elif kind == 'objects':
            sample.objects = {name: ObjectState(*state) for name, *state in data}
        elif kind == 'task':
            robot, *state = data
            sample.tasks[robot] = TaskState(*state)
            sample.robots.add(robot)

    def _add_block(self, block: TfBlock) -> None:
        """The ``/tf`` of many samples (a ``tf_block``), composed for all of them at once
        (:func:`_compose_layout`: the numbers of a ``tf`` record per sample)."""
        moving, robots = _bodies_of(block.frames)
        composed = _compose_layout(block.frames, block.positions, block.quaternions)
        by_time = self.by_time
        for i, t_ns in enumerate(block.times.tolist()):
            sample = by_time.get(t_ns)
            if sample is None:
                sample = by_time[t_ns] = Sample(t_ns / 1e9)
            sample.poses.add_composed(block.frames, block.positions[i], block.quaternions[i],
                                      [(p[i], r[i]) for p, r in composed])
            sample.moving |= moving
            sample.robots |= robots

    def finish(self, bag: str | os.PathLike[str]) -> tuple[Any, list[Sample]]:
        """The projection's info and its samples in time order, each with the static
        frames as well.

        Raises:
            ProjectionError: kind ``bag_error`` (about ``bag``) without a projection's info.
        """
        if self.info is None:
            raise ProjectionError(ErrorKind.BAG_ERROR, f'{bag}: no projection info')
        for t_ns, fluids in self.particles.items():
            if t_ns in self.by_time:
                self.by_time[t_ns].particles = fluids
        for t_ns, fluids in self.batter.items():
            if t_ns in self.by_time:
                self.by_time[t_ns].batter = fluids
        samples = [self.by_time[t] for t in sorted(self.by_time)]
        # Bonds are logged when they change: each sample has those last logged.
        bonds: dict[str, np.ndarray] = {}
        changes = sorted(self.bonds.items())
        k = 0
        for t_ns in sorted(self.by_time):
            while k < len(changes) and changes[k][0] <= t_ns:
                bonds = {**bonds, **changes[k][1]}
                k += 1
            self.by_time[t_ns].bonds = bonds
        _compose_all([sample.poses for sample in samples])
        for sample in samples:
            for name, pose in self.static.items():
                sample.poses.setdefault(name, pose)
        return self.info, samples


def _bodies_of(frames: Iterable[tuple[str, str]]) -> tuple[set[str], set[str]]:
    """The moving bodies and the robots of a tf message's frames ``(parent, child)``: a
    frame without ``/`` is a body; a link frame whose parent is not the world is a link of
    a robot's chain."""
    moving, robots = set(), set()
    for parent, child in frames:
        if '/' not in child:
            moving.add(child)
        elif parent != 'world':
            robots.add(parent.split('/', 1)[0])
    return moving, robots


def _poses(transforms: Iterable[tuple[str, str, Any, Any]]
           ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """World poses of the frames of a tf message (``(parent, child, position, quaternion)``
    each): see :class:`Poses`."""
    poses = Poses()
    poses.add(transforms)
    return dict(poses.items())


class Poses:
    """World poses ``(position, rotation matrix)`` of a sample's frames by name, each
    composed when first asked for (most frames of a robot's link chain never are).

    A frame whose parent is a frame before it in the same tf message (a robot's link chain,
    parents first) is composed with it; other parents are the world.
    """

    __slots__ = ('_frames', 'messages')

    def __init__(self) -> None:
        # name -> [parent's entry or None, position, quaternion, pose once composed]
        self._frames: dict[str, list[Any]] = {}
        self.messages: list[list[tuple[str, str, Any, Any]]] = []

    def add(self, transforms: Iterable[tuple[str, str, Any, Any]]) -> None:
        """The frames of one tf message."""
        transforms = list(transforms)
        entries: dict[str, list[Any]] = {}
        get = entries.get
        for parent, child, position, quaternion in transforms:
            entries[child] = [get(parent), position, quaternion, None]
        self._frames.update(entries)
        self.messages.append(transforms)

    def add_composed(self, frames: tuple[tuple[str, str], ...], positions: np.ndarray,
                     quaternions: np.ndarray, poses: list[tuple[np.ndarray, np.ndarray]]
                     ) -> None:
        """The frames ``(parent, child)`` of one tf message with their logged positions and
        quaternions (k x 3, k x 4) and their world poses, composed already."""
        entries: dict[str, list[Any]] = {}
        get = entries.get
        for (parent, child), position, quaternion, pose in zip(frames, positions,
                                                               quaternions, poses):
            entries[child] = [get(parent), position, quaternion, pose]
        self._frames.update(entries)

    def __contains__(self, name: str) -> bool:
        return name in self._frames

    def __getitem__(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        return _composed(self._frames[name])

    def get(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """The pose of frame ``name``, None without such a frame."""
        entry = self._frames.get(name)
        return None if entry is None else _composed(entry)

    def setdefault(self, name: str, pose: tuple[np.ndarray, np.ndarray]) -> None:
        """Frame ``name`` at ``pose`` (already composed), unless there is one."""
        if name not in self._frames:
            self._frames[name] = [None, None, None, pose]

    def quaternion(self, name: str) -> tuple[float, float, float, float]:
        """The world orientation ``(x, y, z, w)`` of frame ``name``: as logged for a frame
        whose parent is the world, else of its composed rotation."""
        entry = self._frames[name]
        if entry[0] is None and entry[2] is not None:
            return tuple(float(v) for v in entry[2])
        return quaternion_of(_composed(entry)[1])

    def names(self) -> Iterator[str]:
        """Every frame's name, in the order of :meth:`items` (none composed)."""
        return iter(self._frames)

    def items(self) -> Iterator[tuple[str, tuple[np.ndarray, np.ndarray]]]:
        """Every frame's name and pose."""
        return ((name, _composed(entry)) for name, entry in self._frames.items())


def _compose_all(samples: list[Poses]) -> None:
    """Compose the frames of all samples whose one tf message has the same frames, frame
    by frame for all of them at once: the same numbers as :func:`_composed` (element-wise
    arithmetic, and numpy's matrix products of a stack are those of each matrix)."""
    layouts: dict[tuple[tuple[str, str], ...], list[Poses]] = defaultdict(list)
    for poses in samples:
        if len(poses.messages) == 1:
            layouts[tuple([(parent, child) for parent, child, _, _ in poses.messages[0]])
                    ].append(poses)
    for layout, group in layouts.items():
        if len(group) < 2:
            continue
        messages = [poses.messages[0] for poses in group]
        # The same doubles as np.array of the nested lists, without numpy's walk of them.
        shape = (len(messages), len(layout))
        positions = np.fromiter(
            chain.from_iterable([frame[2] for m in messages for frame in m]),
            float, count=shape[0] * shape[1] * 3).reshape(*shape, 3)
        quaternions = np.fromiter(
            chain.from_iterable([frame[3] for m in messages for frame in m]),
            float, count=shape[0] * shape[1] * 4).reshape(*shape, 4)
        for (_, child), (position, rotation) in zip(
                layout, _compose_layout(layout, positions, quaternions)):
            for poses, p, r in zip(group, position, rotation):
                poses._frames[child][3] = (p, r)


def _compose_layout(layout: tuple[tuple[str, str], ...], positions: np.ndarray,
                    quaternions: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The world poses (positions (n, 3), rotations (n, 3, 3)) of each frame of
    ``layout`` in n messages of those frames (``positions`` (n, k, 3), ``quaternions``
    (n, k, 4)): a frame whose parent is a frame before it is composed with it."""
    composed: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    out = []
    for k, (parent_frame, child) in enumerate(layout):
        position = np.ascontiguousarray(positions[:, k])
        rotation = _matrices(quaternions[:, k])
        parent = composed.get(parent_frame)
        if parent is not None:
            position = parent[0] + np.matmul(parent[1], position[:, :, None])[:, :, 0]
            rotation = np.matmul(parent[1], rotation)
        composed[child] = (position, rotation)
        out.append((position, rotation))
    return out


def _matrices(q: np.ndarray) -> np.ndarray:
    """:func:`_matrix` of each row of ``q`` (n x 4)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    m = np.empty((len(q), 3, 3))
    m[:, 0, 0] = 1 - 2 * (y * y + z * z)
    m[:, 0, 1] = 2 * (x * y - z * w)
    m[:, 0, 2] = 2 * (x * z + y * w)
    m[:, 1, 0] = 2 * (x * y + z * w)
    m[:, 1, 1] = 1 - 2 * (x * x + z * z)
    m[:, 1, 2] = 2 * (y * z - x * w)
    m[:, 2, 0] = 2 * (x * z - y * w)
    m[:, 2, 1] = 2 * (y * z + x * w)
    m[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def _composed(entry: list[Any]) -> tuple[np.ndarray, np.ndarray]:
    pose = entry[3]
    if pose is None:
        parent, t, q = entry[0], entry[1], entry[2]
        position, rotation = np.array(t), _matrix(q)
        if parent is not None:
            parent = _composed(parent)
            position, rotation = parent[0] + parent[1] @ position, parent[1] @ rotation
        pose = entry[3] = (position, rotation)
    return pose


def _matrix(q: tuple[float, float, float, float]) -> np.ndarray:
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
