"""Key frames of a projection, rendered from its bag.

The bag alone is enough: ``/projection/markers`` gives each body's visual shapes (frame id =
body or link name), ``/tf_static`` and ``/tf`` their poses over time, ``/projection/objects``
whether an object is broken. Rendering rebuilds visual-only bodies in a private PyBullet
DIRECT client and takes a TinyRenderer camera image, which needs no display.

    >>> scene = BagScene.load(bag)
    >>> image = render_frame(scene, 1.5, target='egg1')   # (H, W, 3) uint8
    >>> save_png(image, 'frame.png')
"""

from __future__ import annotations

import bisect
import contextlib
from dataclasses import dataclass, field
import os
from pathlib import Path
import sys
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.geometry import quaternion_product

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

    from projection_server.reproduce.experiments import Event

__all__ = [
    'BROKEN_COLOR',
    'BagScene',
    'RenderError',
    'key_times',
    'render_frame',
    'render_strip',
    'save_png',
]

WORLD_FRAMES = frozenset({'world', 'map', ''})
BROKEN_COLOR = (0.95, 0.7, 0.1, 1.0)   # a broken object is drawn as yolk

# visualization_msgs/Marker types
_CUBE, _SPHERE, _CYLINDER = 1, 2, 3
_CUBE_LIST, _SPHERE_LIST, _POINTS = 6, 7, 8
_TRIANGLE_LIST = 11
_ADD, _DELETE, _DELETEALL = 0, 2, 3


class RenderError(Exception):
    """A bag could not be read or rendered."""


@dataclass
class _Track:
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
    """The shapes and poses of one projection's bag, replayable at any time (seconds)."""

    tracks: dict[str, _Track]
    marker_updates: list[tuple[float, list[tuple[str, int, int, Shape | None]]]]
    broken: list[tuple[float, frozenset[str]]]
    duration: float

    @classmethod
    def load(cls, bag: str | Path) -> BagScene:
        """Read a projection's bag (a directory with an MCAP file)."""
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import get_typestore, Stores

        raw_tracks: dict[str, tuple[str, list]] = {}
        updates, broken = [], []
        end = 0.0
        try:
            with AnyReader([Path(bag)],
                           default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
                start = reader.start_time
                topics = {'/tf', '/tf_static', '/projection/markers', '/projection/objects'}
                conns = [c for c in reader.connections if c.topic in topics]
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
                    else:
                        broken.append((t, frozenset(o.name for o in msg.objects if o.broken)))
        except Exception as exc:  # rosbags raises several unrelated types
            message = f'cannot read bag {bag}: {exc}'
            raise RenderError(message) from exc
        if not updates:
            message = f'bag {bag} has no /projection/markers: nothing to draw'
            raise RenderError(message)
        tracks = {name: _Track(parent, [s[0] for s in samples],
                               np.array([s[1] for s in samples], dtype=float),
                               np.array([s[2] for s in samples], dtype=float))
                  for name, (parent, samples) in raw_tracks.items()}
        return cls(tracks, updates, broken, end)

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
            xyz, quat = _compose(track.xyz[i], track.quat[i], xyz, quat)
            frame = track.parent
        return xyz, quat


def render_frame(scene: BagScene, t: float, *, target: str | None = None,
                 distance: float = 0.45, yaw: float = 20.0, pitch: float = -15.0,
                 lift: float = 0.05, width: int = 480, height: int = 360,
                 hide: Iterable[str] = (), mark_broken: bool = True) -> np.ndarray:
    """Render the scene at ``t`` seconds as an (height, width, 3) uint8 RGB image.

    The camera looks at ``target``'s position at the start of the projection (raised by
    ``lift``), so that motion shows against a still background; without a target it looks at
    the centroid of the moving bodies. Frames named in ``hide`` are not drawn; broken objects
    are drawn in :data:`BROKEN_COLOR` unless ``mark_broken`` is false.
    """
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

    hidden = set(hide)
    broken = scene.broken_at(t) if mark_broken else frozenset()
    with _quiet_stdout():   # pybullet's C code prints 'argv[0]=' on connect
        client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        for shape in scene.shapes_at(t):
            if shape.frame in hidden:
                continue
            rgba = BROKEN_COLOR if shape.frame in broken else shape.rgba
            visual = _visual_shape(client, shape, rgba)
            if visual < 0:
                continue
            frame_xyz, frame_quat = scene.pose(shape.frame, t)
            xyz, quat = _compose(np.array(shape.xyz), np.array(shape.quat),
                                 frame_xyz, frame_quat)
            client.createMultiBody(baseMass=0.0, baseVisualShapeIndex=visual,
                                   basePosition=xyz.tolist(), baseOrientation=quat.tolist())
        focus = _focus(scene, target) + np.array([0.0, 0.0, lift])
        view = client.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=focus.tolist(), distance=distance, yaw=yaw, pitch=pitch,
            roll=0.0, upAxisIndex=2)
        projection = client.computeProjectionMatrixFOV(fov=50.0, aspect=width / height,
                                                       nearVal=0.01, farVal=20.0)
        _, _, rgba, _, _ = client.getCameraImage(
            width, height, viewMatrix=view, projectionMatrix=projection,
            renderer=pybullet.ER_TINY_RENDERER, lightDirection=[0.4, -0.6, 1.0],
            shadow=0)
    finally:
        client.disconnect()
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()


def key_times(events: Sequence[Event], duration: float, *,
              limit: int = 5, minimum: int = 4) -> list[tuple[float, str]]:
    """Times worth a frame: the start, each event (interval events at their middle), the end.

    Events closer than 0.1 s to an earlier chosen time are merged into its label; at most
    ``limit`` frames. With fewer than ``minimum`` frames (a pour has no event of its own),
    evenly spaced ones fill the longest gaps.
    """
    chosen: list[tuple[float, str]] = [(0.0, 'start')]
    for event in sorted(events, key=lambda e: e.start):
        t = 0.5 * (event.start + event.end)
        if abs(chosen[-1][0] - t) < 0.1:
            chosen[-1] = (chosen[-1][0], f'{chosen[-1][1]}, {event.term}')
        elif len(chosen) < limit - 1:
            chosen.append((t, event.term))
    if duration - chosen[-1][0] > 0.1:
        chosen.append((duration, 'end'))
    while 2 <= len(chosen) < min(minimum, limit):
        gaps = [b[0] - a[0] for a, b in zip(chosen, chosen[1:])]
        i = gaps.index(max(gaps))   # the longest gap, the earliest of equal ones
        t = chosen[i][0] + gaps[i] / 2
        chosen.insert(i + 1, (t, ''))
    return chosen


def render_strip(scene: BagScene, times: Sequence[tuple[float, str]], path: str | Path, *,
                 caption: str = '', target: str | None = None) -> Path:
    """Render ``times`` (seconds, label) side by side into one PNG at ``path``."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    frames = [render_frame(scene, t, target=target) for t, _ in times]
    fig, axes = plt.subplots(1, len(frames), figsize=(3.2 * len(frames), 2.8), squeeze=False)
    for ax, image, (t, label) in zip(axes[0], frames, times):
        ax.imshow(image)
        ax.set_title(f't = {t:.2f} s' + (f'\n{label}' if label else ''), fontsize=9)
        ax.axis('off')
    if caption:
        fig.suptitle(caption, fontsize=11)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.92 if caption else 1.0))
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def save_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an RGB image as a PNG file."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    path = Path(path)
    plt.imsave(path, image)
    return path


# -- internals -----------------------------------------------------------------------------

@contextlib.contextmanager
def _quiet_stdout():
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, 'wb') as devnull:
            os.dup2(devnull.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _marker_update(m: Any) -> tuple[str, int, int, Shape | None]:
    if m.action in (_DELETE, _DELETEALL):
        return m.ns, m.id, m.action, None
    p, q, s, c = m.pose.position, m.pose.orientation, m.scale, m.color
    quat = (q.x, q.y, q.z, q.w) if (q.x, q.y, q.z, q.w) != (0, 0, 0, 0) else (0, 0, 0, 1)
    shape = Shape(m.header.frame_id, m.type, (p.x, p.y, p.z), quat, (s.x, s.y, s.z),
                  (c.r, c.g, c.b, c.a if c.a > 0 else 1.0),
                  [(pt.x, pt.y, pt.z) for pt in m.points])
    return m.ns, m.id, m.action, shape


def _visual_shape(client: Any, shape: Shape, rgba: Sequence[float]) -> int:
    import pybullet

    sx, sy, sz = shape.scale
    if shape.kind == _CUBE:
        return client.createVisualShape(pybullet.GEOM_BOX, halfExtents=[sx / 2, sy / 2, sz / 2],
                                         rgbaColor=list(rgba))
    if shape.kind == _SPHERE:
        vertices, normals, indices = _ellipsoid(sx / 2, sy / 2, sz / 2)
    elif shape.kind == _CYLINDER:
        vertices, normals, indices = _cylinder(sx / 2, sy / 2, sz)
    elif shape.kind in (_SPHERE_LIST, _CUBE_LIST, _POINTS) and shape.points:
        # Particles: one mesh of small spheres, far cheaper than a body per particle.
        unit = _ellipsoid(sx / 2, sy / 2, (sz or sx) / 2, rings=4, segments=6)
        vertices, normals, indices = _replicate(unit, shape.points)
    elif shape.kind == _TRIANGLE_LIST and len(shape.points) >= 3:
        vertices = np.array(shape.points[:len(shape.points) // 3 * 3]) * np.array(shape.scale)
        normals = _face_normals(vertices)
        indices = np.arange(len(vertices))
    else:
        return -1  # arrows, lines, text, meshes by resource: not drawn
    return client.createVisualShape(pybullet.GEOM_MESH, vertices=vertices.tolist(),
                                    normals=normals.tolist(),
                                    indices=[int(i) for i in indices],
                                    rgbaColor=list(rgba))


def _ellipsoid(a: float, b: float, c: float, rings: int = 12,
               segments: int = 20) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2 * np.pi, segments + 1)
    th, ph = np.meshgrid(theta, phi, indexing='ij')
    unit = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    vertices = (unit * np.array([a, b, c])).reshape(-1, 3)
    normals = unit / np.array([a, b, c])
    normals = (normals / np.linalg.norm(normals, axis=-1, keepdims=True)).reshape(-1, 3)
    indices = []
    width = segments + 1
    for i in range(rings):
        for j in range(segments):
            v0, v1 = i * width + j, i * width + j + 1
            v2, v3 = v0 + width, v1 + width
            indices += [v0, v2, v1, v1, v2, v3]
    return vertices, normals, np.array(indices)


def _cylinder(a: float, b: float, height: float,
              segments: int = 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    phi = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([a * np.cos(phi), b * np.sin(phi)], -1)
    side_n = np.stack([np.cos(phi) / a, np.sin(phi) / b, np.zeros_like(phi)], -1)
    side_n /= np.linalg.norm(side_n, axis=-1, keepdims=True)
    h = height / 2
    bottom = np.column_stack([ring, np.full(segments, -h)])
    top = np.column_stack([ring, np.full(segments, h)])
    vertices = [bottom, top, bottom, top, [[0, 0, -h]], [[0, 0, h]]]
    normals = [side_n, side_n, np.tile([0, 0, -1.0], (segments, 1)),
               np.tile([0, 0, 1.0], (segments, 1)), [[0, 0, -1.0]], [[0, 0, 1.0]]]
    n = segments
    indices = []
    for j in range(n):
        k = (j + 1) % n
        indices += [j, k, n + j, k, n + k, n + j]                   # side
        indices += [4 * n, 2 * n + k, 2 * n + j]                     # bottom cap
        indices += [4 * n + 1, 3 * n + j, 3 * n + k]                 # top cap
    return (np.vstack(vertices).astype(float), np.vstack(normals).astype(float),
            np.array(indices))


def _replicate(unit: tuple[np.ndarray, np.ndarray, np.ndarray],
               points: Sequence[tuple[float, float, float]]):
    vertices, normals, indices = unit
    centres = np.asarray(points, dtype=float)
    all_vertices = (vertices[None, :, :] + centres[:, None, :]).reshape(-1, 3)
    all_normals = np.tile(normals, (len(centres), 1))
    offsets = (np.arange(len(centres)) * len(vertices))[:, None]
    return all_vertices, all_normals, (indices[None, :] + offsets).reshape(-1)


def _face_normals(vertices: np.ndarray) -> np.ndarray:
    tri = vertices.reshape(-1, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    return np.repeat(n, 3, axis=0)


def _focus(scene: BagScene, target: str | None) -> np.ndarray:
    if target is not None and target in scene.tracks:
        return scene.pose(target, 0.0)[0]
    moving = [name for name, track in scene.tracks.items() if len(track.times) > 1]
    if not moving:
        return np.zeros(3)
    return np.mean([scene.pose(name, 0.0)[0] for name in moving], axis=0)


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    qv = np.array([*v, 0.0])
    conj = np.array([-q[0], -q[1], -q[2], q[3]])
    return quaternion_product(quaternion_product(q, qv), conj)[:3]


def _compose(xyz: np.ndarray, quat: np.ndarray, parent_xyz: np.ndarray,
             parent_quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pose (xyz, quat) given in the parent frame, expressed in the parent's parent."""
    return parent_xyz + _rotate(parent_quat, xyz), quaternion_product(parent_quat, quat)
