"""What a projection's bag shows, replayable at any time: shapes, robots and poses.

``/projection/markers`` gives each body's visual shapes (frame id = body or link name),
``/tf_static`` and ``/tf`` their poses over time, ``/projection/objects`` whether an object
is broken, and each robot's ``robot_description`` (``/robot_description``,
``/R/robot_description``) its links' visuals (:mod:`projection_server.render.robots`), with
``/projection/info``'s scenario saying which URDF file it was (where its meshes lie).

    >>> scene = BagScene.load(bag)
    >>> scene.pose('panda_robot/panda_hand', 1.5)   # (xyz, quaternion x, y, z, w)
"""

from __future__ import annotations

import bisect
import contextlib
from dataclasses import dataclass, field
import json
from pathlib import Path
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.geometry import quaternion_product

if TYPE_CHECKING:
    from collections.abc import Iterable

    from projection_server.render.robots import RobotModel

__all__ = ['BagScene', 'RenderError', 'Shape', 'Track', 'WORLD_FRAMES', 'compose']

WORLD_FRAMES = frozenset({'world', 'map', ''})

# visualization_msgs/Marker actions
_DELETE, _DELETEALL = 2, 3


class RenderError(Exception):
    """A bag could not be read or rendered."""


@dataclass
class Track:
    """A frame's poses in its parent frame over time (seconds)."""

    parent: str
    times: list[float]
    xyz: np.ndarray    # (n, 3)
    quat: np.ndarray   # (n, 4) x, y, z, w


@dataclass
class Shape:
    """One marker reduced to what rendering needs; ``pose`` is relative to ``frame``."""

    frame: str
    kind: int
    xyz: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    scale: tuple[float, float, float]
    rgba: tuple[float, float, float, float]
    points: list[tuple[float, float, float]] = field(default_factory=list)


@dataclass
class BagScene:
    """The shapes, robots and poses of one projection's bag, at any time (seconds)."""

    tracks: dict[str, Track]
    marker_updates: list[tuple[float, list[tuple[str, int, int, Shape | None]]]]
    broken: list[tuple[float, frozenset[str]]]
    duration: float
    robots: list[RobotModel] = field(default_factory=list)

    @classmethod
    def load(cls, bag: str | Path, assets: Iterable[str | Path] = ()) -> BagScene:
        """Read a projection's bag (a directory with an MCAP file). Robots' meshes are
        looked up in ``assets`` too (:func:`~projection_server.render.robots.parse_robot`).

        Raises:
            RenderError: the bag cannot be read or has no markers.
        """
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import get_typestore, Stores

        from projection_server.render.robots import parse_robot

        raw_tracks: dict[str, tuple[str, list]] = {}
        updates, broken, descriptions = [], [], []
        files: dict[str, str] = {}
        end = 0.0
        if not Path(bag).exists():
            raise RenderError(f'no such bag: {bag}')
        try:
            with AnyReader([Path(bag)],
                           default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
                start = reader.start_time
                topics = {'/tf', '/tf_static', '/projection/markers', '/projection/objects',
                          '/projection/info'}
                conns = [c for c in reader.connections if c.topic in topics
                         or c.topic.endswith('/robot_description')]
                for conn, stamp, raw in reader.messages(connections=conns):
                    t = (stamp - start) * 1e-9
                    end = max(end, t)
                    msg = reader.deserialize(raw, conn.msgtype)
                    if conn.topic in ('/tf', '/tf_static'):
                        for tr in msg.transforms:
                            track = raw_tracks.setdefault(tr.child_frame_id,
                                                          (tr.header.frame_id, []))
                            q, v = tr.transform.rotation, tr.transform.translation
                            track[1].append((t, (v.x, v.y, v.z), (q.x, q.y, q.z, q.w)))
                    elif conn.topic == '/projection/markers':
                        updates.append((t, [_marker_update(m) for m in msg.markers]))
                    elif conn.topic == '/projection/objects':
                        broken.append((t, frozenset(o.name for o in msg.objects if o.broken)))
                    elif conn.topic == '/projection/info':
                        files = _model_files(msg.scenario_json)
                    else:
                        descriptions.append((conn.topic, msg.data))
        except Exception as exc:  # rosbags raises several unrelated types
            message = f'cannot read bag {bag}: {exc}'
            raise RenderError(message) from exc
        if not updates:
            message = f'bag {bag} has no /projection/markers: nothing to draw'
            raise RenderError(message)
        tracks = {name: Track(parent, [s[0] for s in samples],
                               np.array([s[1] for s in samples], dtype=float),
                               np.array([s[2] for s in samples], dtype=float))
                  for name, (parent, samples) in raw_tracks.items()}
        robots = [parse_robot(text, topic, assets, files) for topic, text in descriptions]
        return cls(tracks, updates, broken, end, robots)

    def shapes_at(self, t: float) -> list[Shape]:
        """The markers in effect at time ``t`` (ADD/MODIFY, DELETE and DELETEALL applied)."""
        current: dict[tuple[str, int], Shape] = {}
        for stamp, markers in self.marker_updates:
            if stamp > t + 1e-9:
                break
            for ns, ident, action, shape in markers:
                if action == _DELETEALL:
                    current.clear()
                elif action == _DELETE:
                    current.pop((ns, ident), None)
                elif shape is not None:
                    current[(ns, ident)] = shape
        return list(current.values())

    def marker_frames(self) -> frozenset[str]:
        """Every frame some marker is drawn in, at any time."""
        return frozenset(shape.frame for _, markers in self.marker_updates
                         for _, _, _, shape in markers if shape is not None)

    def broken_at(self, t: float) -> frozenset[str]:
        names: frozenset[str] = frozenset()
        for stamp, value in self.broken:
            if stamp > t + 1e-9:
                break
            names = value
        return names

    def pose(self, frame: str, t: float) -> tuple[np.ndarray, np.ndarray]:
        """World position and quaternion (x, y, z, w) of ``frame`` at ``t``."""
        xyz, quat = np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
        seen = set()
        while frame not in WORLD_FRAMES and frame in self.tracks and frame not in seen:
            seen.add(frame)
            track = self.tracks[frame]
            i = max(0, bisect.bisect_right(track.times, t + 1e-9) - 1)
            xyz, quat = compose(xyz, quat, track.xyz[i], track.quat[i])
            frame = track.parent
        return xyz, quat


def _model_files(scenario_json: str) -> dict[str, str]:
    """Entity name -> the model file (URDF) its scenario names, as the bag's maker had it."""
    files: dict[str, str] = {}
    with contextlib.suppress(ValueError, TypeError, AttributeError):
        pending = list(json.loads(scenario_json).get('entities', []))
        while pending:
            entity = pending.pop()
            pending += entity.get('parts', [])
            properties = entity.get('properties', {})
            for key in ('file', 'urdf'):
                if isinstance(properties.get(key), str):
                    files[entity['name']] = properties[key]
    return files


def _marker_update(m: Any) -> tuple[str, int, int, Shape | None]:
    if m.action in (_DELETE, _DELETEALL):
        return m.ns, m.id, m.action, None
    p, q, s, c = m.pose.position, m.pose.orientation, m.scale, m.color
    quat = (q.x, q.y, q.z, q.w) if (q.x, q.y, q.z, q.w) != (0, 0, 0, 0) else (0, 0, 0, 1)
    shape = Shape(m.header.frame_id, m.type, (p.x, p.y, p.z), quat, (s.x, s.y, s.z),
                  (c.r, c.g, c.b, c.a if c.a > 0 else 1.0),
                  [(pt.x, pt.y, pt.z) for pt in m.points])
    return m.ns, m.id, m.action, shape


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    qv = np.array([*v, 0.0])
    conj = np.array([-q[0], -q[1], -q[2], q[3]])
    return quaternion_product(quaternion_product(q, qv), conj)[:3]


def compose(xyz: np.ndarray, quat: np.ndarray, parent_xyz: np.ndarray,
            parent_quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pose (xyz, quat) given in the parent frame, expressed in the parent's parent."""
    return parent_xyz + _rotate(parent_quat, xyz), quaternion_product(parent_quat, quat)
