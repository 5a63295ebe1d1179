"""A buffer of the robot's transforms, kept and looked up as tf2 does it.

Each child frame keeps the transforms to its parent of the last :data:`CACHE_TIME` seconds
(``/tf``), in stamp order; a static transform (``/tf_static``) is kept, the latest per
child, and never expires. A lookup composes the chain between two frames through their
common ancestor:

* at a time, each link of the chain interpolated there (linear in translation, spherical
  in rotation), or an error if a link has no transform that early or that late;
* at the latest, at the *latest common time*: the newest time at which every non-static
  link of the chain has a transform (tf2's ``Time(0)``). Its age is what staleness is
  judged by; a chain of static links only has no age.

Pure Python and numpy: the ROS subscriptions that feed it live in :mod:`.listener`.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
import math
import threading
from typing import Iterable

import numpy as np

from projection_server.geometry import quaternion_product
from projection_server.world.errors import GraphError

__all__ = ['CACHE_TIME', 'TransformError', 'Transform', 'TransformBuffer', 'compose', 'invert']

CACHE_TIME = 10.0   # s of /tf kept per frame, tf2's default cache time


class TransformError(GraphError):
    """A lookup that cannot be answered; :attr:`kind` is ``unknown``, ``unconnected`` or
    ``extrapolation``, :attr:`frame` the frame it is about."""

    @property
    def frame(self) -> str:
        return self.subject


@dataclass(frozen=True)
class Transform:
    """A child frame's pose in its parent frame at ``stamp`` (ns; None: static)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]   # x, y, z, w
    stamp: int | None = None


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    u, w = q[:3], q[3]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def compose(a: tuple[np.ndarray, np.ndarray],
            b: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``a * b``: the pose ``b`` (in a's child frame) expressed in a's parent frame."""
    return a[0] + _rotate(a[1], b[0]), quaternion_product(a[1], b[1])


def invert(a: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    conj = np.array([-a[1][0], -a[1][1], -a[1][2], a[1][3]])
    return -_rotate(conj, a[0]), conj


def _normalized(q: Iterable[float]) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    n = float(np.linalg.norm(q))
    return q / n if n > 0 else np.array([0.0, 0.0, 0.0, 1.0])


def _slerp(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    dot = float(np.dot(a, b))
    if dot < 0.0:
        b, dot = -b, -dot
    if dot > 0.9995:
        return _normalized(a + t * (b - a))
    theta = math.acos(dot)
    return (math.sin((1 - t) * theta) * a + math.sin(t * theta) * b) / math.sin(theta)


class _Cache:
    """One child frame's transforms: its static one, or its recent ones by stamp."""

    __slots__ = ('parent', 'static', 'stamps', 'poses')

    def __init__(self, parent: str):
        self.parent = parent
        self.static: tuple | None = None    # (translation, rotation) as received
        self.stamps: list[int] = []
        self.poses: list[tuple] = []

    def insert(self, stamp: int, pose: tuple, keep_ns: int) -> None:
        if not self.stamps or stamp > self.stamps[-1]:
            self.stamps.append(stamp)
            self.poses.append(pose)
        else:
            i = bisect.bisect_left(self.stamps, stamp)
            if i < len(self.stamps) and self.stamps[i] == stamp:
                self.poses[i] = pose
            else:
                self.stamps.insert(i, stamp)
                self.poses.insert(i, pose)
        cut = bisect.bisect_left(self.stamps, self.stamps[-1] - keep_ns)
        if cut:
            del self.stamps[:cut], self.poses[:cut]

    def latest(self) -> int | None:
        return None if self.static is not None else self.stamps[-1]

    def at(self, stamp: int, child: str) -> tuple[np.ndarray, np.ndarray]:
        if self.static is not None:
            return _pose(self.static)
        stamps = self.stamps
        if stamp < stamps[0] or stamp > stamps[-1]:
            side = 'before the oldest' if stamp < stamps[0] else 'after the newest'
            raise TransformError('extrapolation', child, (
                f'the transform {self.parent} -> {child} is not known at '
                f'{stamp / 1e9:.3f} s: that is {side} one kept '
                f'({stamps[0] / 1e9:.3f}-{stamps[-1] / 1e9:.3f} s)'))
        i = bisect.bisect_left(stamps, stamp)
        if stamps[i] == stamp:
            return _pose(self.poses[i])
        t = (stamp - stamps[i - 1]) / (stamps[i] - stamps[i - 1])
        (p0, q0), (p1, q1) = _pose(self.poses[i - 1]), _pose(self.poses[i])
        return p0 + t * (p1 - p0), _slerp(q0, q1, t)


def _pose(raw: tuple) -> tuple[np.ndarray, np.ndarray]:
    """A kept transform as arrays, its quaternion normalized: done at lookup, not when it
    arrives, since a robot sends hundreds a second and a query looks up a few."""
    return np.asarray(raw[0], dtype=float), _normalized(raw[1])


class TransformBuffer:
    """The transforms received on ``/tf`` and ``/tf_static``, safe to use from several
    threads (subscription callbacks add, queries look up)."""

    def __init__(self, cache_time: float = CACHE_TIME):
        self._keep = int(cache_time * 1e9)
        self._frames: dict[str, _Cache] = {}
        self._lock = threading.Lock()

    def add(self, transform: Transform) -> None:
        """Keep ``transform`` (static if its stamp is None). A frame's parent is the one
        of its latest transform, as tf2's."""
        pose = (transform.translation, transform.rotation)
        with self._lock:
            cache = self._frames.get(transform.child)
            if cache is None or cache.parent != transform.parent:
                cache = self._frames[transform.child] = _Cache(transform.parent)
            if transform.stamp is None:
                cache.static = pose
            else:
                cache.static = None
                cache.insert(transform.stamp, pose, self._keep)

    def frames(self) -> list[str]:
        """Every frame known, parents included, sorted."""
        with self._lock:
            names = set(self._frames) | {c.parent for c in self._frames.values()}
        return sorted(names)

    def lookup(self, target: str, source: str, stamp: int | None = None
               ) -> tuple[tuple[np.ndarray, np.ndarray], int | None]:
        """The pose of frame ``source`` in frame ``target`` at ``stamp`` (ns), or at the
        latest common time (None), and the time it is for (None: all static).

        Raises:
            TransformError: a frame no transform names (``unknown``), two frames of
                different trees (``unconnected``), a time outside a link's kept
                transforms (``extrapolation``).
        """
        with self._lock:
            up_source = self._chain(source, target)
            up_target = self._chain(target, source)
            common = next((f for f, _ in up_source if f in {g for g, _ in up_target}), None)
            if common is None:
                raise TransformError('unconnected', source, (
                    f'frames {source} and {target} are not connected: {source} is under '
                    f'{up_source[-1][0]}, {target} under {up_target[-1][0]}'))
            links = ([c for f, c in up_source[:_index(up_source, common)]],
                     [c for f, c in up_target[:_index(up_target, common)]])
            if stamp is None:
                latest = [c.latest() for c in links[0] + links[1]]
                dynamic = [s for s in latest if s is not None]
                stamp = min(dynamic) if dynamic else None
            at = 0 if stamp is None else stamp
            frames_s = [f for f, _ in up_source]
            frames_t = [f for f, _ in up_target]
            pose_s = _up(links[0], frames_s, at)   # source in common
            pose_t = _up(links[1], frames_t, at)   # target in common
        return compose(invert(pose_t), pose_s), stamp

    def _chain(self, frame: str, other: str) -> list[tuple[str, _Cache | None]]:
        """``(frame, its cache)`` from ``frame`` up to its tree's root (cache None)."""
        if frame not in self._frames and not any(c.parent == frame
                                                 for c in self._frames.values()):
            known = sorted(set(self._frames) | {c.parent for c in self._frames.values()})
            raise TransformError('unknown', frame, (
                f'frame {frame} does not exist'
                + (f' (known: {", ".join(known)})' if known else ' (no transform received)')))
        chain, seen = [], set()
        while frame in self._frames and frame not in seen:
            seen.add(frame)
            cache = self._frames[frame]
            chain.append((frame, cache))
            frame = cache.parent
        chain.append((frame, None))
        return chain


def _index(chain: list[tuple[str, _Cache | None]], frame: str) -> int:
    return next(i for i, (f, _) in enumerate(chain) if f == frame)


def _up(caches: list[_Cache], frames: list[str], stamp: int
        ) -> tuple[np.ndarray, np.ndarray]:
    """The first frame's pose in the frame above the last cache, through ``caches``."""
    pose = (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    for cache, child in zip(caches, frames):
        pose = compose(cache.at(stamp, child), pose)
    return pose
