"""Frames of a projection rendered from its bag: the objects' markers and every robot's
links at their ``/tf`` poses, in a private PyBullet DIRECT client with a TinyRenderer camera
(no display needed).

    >>> scene = BagScene.load(bag)
    >>> with Renderer(scene) as renderer:
    ...     camera = renderer.camera(target='egg1')
    ...     image = renderer.frame(1.5, camera)       # (H, W, 3) uint8
    >>> save_png(image, 'frame.png')

A :class:`Renderer` makes the robots' link bodies once and moves them for each frame; the
markers' bodies are made for each frame, since shapes may change (a broken egg, particles).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
import os
from pathlib import Path
import sys
from typing import Any, Protocol, TYPE_CHECKING

import numpy as np

from projection_server.render.scene import BagScene, compose
from projection_server.render.shapes import link_visual_shape, marker_visual_shape

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

__all__ = [
    'BROKEN_COLOR',
    'Camera',
    'Renderer',
    'key_times',
    'render_frame',
    'render_strip',
    'save_png',
]

BROKEN_COLOR = (0.95, 0.7, 0.1, 1.0)   # a broken object is drawn as yolk
_FOV = 50.0


class _Event(Protocol):
    term: str
    start: float
    end: float


@dataclass(frozen=True)
class Camera:
    """A camera's view and projection matrices (PyBullet's, column-major) and image size."""

    view: tuple[float, ...]
    projection: tuple[float, ...]
    width: int
    height: int

    def pixel(self, xyz: Sequence[float]) -> tuple[float, float]:
        """The image column and row where the world point ``xyz`` appears."""
        view = np.array(self.view).reshape(4, 4).T
        projection = np.array(self.projection).reshape(4, 4).T
        clip = projection @ view @ np.array([*xyz, 1.0])
        x, y = clip[:2] / clip[3]
        return (x + 1) / 2 * self.width, (1 - y) / 2 * self.height


class Renderer:
    """Renders frames of one bag's scene; close it (or use it as a context manager)."""

    def __init__(self, scene: BagScene, *, robots: bool = True):
        """``robots``: draw the robots' links from their descriptions."""
        import pybullet
        from pybullet_utils.bullet_client import BulletClient

        self.scene = scene
        with _quiet_stdout():   # pybullet's C code prints 'argv[0]=' on connect
            self._client = BulletClient(connection_mode=pybullet.DIRECT)
        self._links: list[tuple[str, int, Any, Any]] = []   # frame, body, offset pose
        if robots:
            # A link the markers already draw (the PR2 gripper's boxes) is not drawn twice.
            drawn = scene.marker_frames()
            for robot in scene.robots:
                for visual in robot.visuals:
                    if visual.frame in drawn or visual.frame not in scene.tracks:
                        continue
                    shape = link_visual_shape(self._client, visual)
                    if shape < 0:
                        continue
                    body = self._client.createMultiBody(baseMass=0.0,
                                                        baseVisualShapeIndex=shape)
                    self._links.append((visual.frame, body, np.array(visual.xyz),
                                        np.array(visual.quat)))

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._client is not None:
            self._client.disconnect()
            self._client = None

    def camera(self, *, target: str | None = None, distance: float | None = 0.45,
               yaw: float = 20.0, pitch: float = -15.0, lift: float = 0.05,
               width: int = 480, height: int = 360) -> Camera:
        """A camera that looks at ``target``'s position at the start of the projection
        (raised by ``lift``), so that motion shows against a still background; without a
        target, at the centre of the moving bodies and robot links. ``distance`` None:
        far enough to see all of those (0.45 m from a target)."""
        focus, radius = _focus(self.scene, target)
        if distance is None:
            distance = max(0.45, 2.0 * radius + 0.2)
        focus = focus + np.array([0.0, 0.0, lift])
        view = self._client.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=focus.tolist(), distance=distance, yaw=yaw, pitch=pitch,
            roll=0.0, upAxisIndex=2)
        projection = self._client.computeProjectionMatrixFOV(
            fov=_FOV, aspect=width / height, nearVal=0.01, farVal=20.0)
        return Camera(tuple(view), tuple(projection), width, height)

    def frame(self, t: float, camera: Camera, *, hide: Iterable[str] = (),
              mark_broken: bool = True) -> np.ndarray:
        """The scene at ``t`` seconds as an (height, width, 3) uint8 RGB image.

        Frames named in ``hide`` are not drawn, nor their links (``hide={'panda_robot'}``
        hides the arm); broken objects are drawn in :data:`BROKEN_COLOR` unless
        ``mark_broken`` is false."""
        import pybullet

        client, scene = self._client, self.scene
        hidden = set(hide)
        broken = scene.broken_at(t) if mark_broken else frozenset()
        away = [0.0, 0.0, -1000.0]   # a hidden robot link goes out of sight
        for frame, body, xyz, quat in self._links:
            if _is_hidden(frame, hidden):
                client.resetBasePositionAndOrientation(body, away, [0, 0, 0, 1])
                continue
            pose = compose(xyz, quat, *scene.pose(frame, t))
            client.resetBasePositionAndOrientation(body, pose[0].tolist(), pose[1].tolist())
        bodies = []
        try:
            for shape in scene.shapes_at(t):
                if _is_hidden(shape.frame, hidden):
                    continue
                rgba = BROKEN_COLOR if shape.frame in broken else shape.rgba
                visual = marker_visual_shape(client, shape, rgba)
                if visual < 0:
                    continue
                xyz, quat = compose(np.array(shape.xyz), np.array(shape.quat),
                                    *scene.pose(shape.frame, t))
                bodies.append(client.createMultiBody(
                    baseMass=0.0, baseVisualShapeIndex=visual, basePosition=xyz.tolist(),
                    baseOrientation=quat.tolist()))
            _, _, rgba, _, _ = client.getCameraImage(
                camera.width, camera.height, viewMatrix=list(camera.view),
                projectionMatrix=list(camera.projection),
                renderer=pybullet.ER_TINY_RENDERER, lightDirection=[0.4, -0.6, 1.0],
                shadow=0)
        finally:
            for body in bodies:
                client.removeBody(body)
        image = np.asarray(rgba, dtype=np.uint8).reshape(camera.height, camera.width, 4)
        return image[:, :, :3].copy()


def render_frame(scene: BagScene, t: float, *, target: str | None = None,
                 distance: float | None = 0.45, yaw: float = 20.0, pitch: float = -15.0,
                 lift: float = 0.05, width: int = 480, height: int = 360,
                 hide: Iterable[str] = (), mark_broken: bool = True) -> np.ndarray:
    """One frame of ``scene`` at ``t`` seconds (:meth:`Renderer.camera`,
    :meth:`Renderer.frame`) as an (height, width, 3) uint8 RGB image."""
    with Renderer(scene) as renderer:
        camera = renderer.camera(target=target, distance=distance, yaw=yaw, pitch=pitch,
                                 lift=lift, width=width, height=height)
        return renderer.frame(t, camera, hide=hide, mark_broken=mark_broken)


def key_times(events: Sequence[_Event], duration: float, *,
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
                 caption: str = '', target: str | None = None,
                 distance: float | None = 0.45, frames: Sequence[np.ndarray] | None = None
                 ) -> Path:
    """Render ``times`` (seconds, label) side by side into one PNG at ``path``; ``frames``:
    the images already rendered for them."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    if frames is None:
        with Renderer(scene) as renderer:
            camera = renderer.camera(target=target, distance=distance)
            frames = [renderer.frame(t, camera) for t, _ in times]
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


def _is_hidden(frame: str, hidden: set[str]) -> bool:
    return bool(hidden) and (frame in hidden or frame.split('/')[0] in hidden)


def _focus(scene: BagScene, target: str | None) -> tuple[np.ndarray, float]:
    """Where to look, and the radius of what moves around it, at the start."""
    if target is not None and target in scene.tracks:
        return scene.pose(target, 0.0)[0], 0.0
    moving = [name for name, track in scene.tracks.items() if len(track.times) > 1]
    if not moving:
        return np.zeros(3), 0.0
    points = np.array([scene.pose(name, 0.0)[0] for name in moving])
    centre = points.mean(axis=0)
    return centre, float(np.linalg.norm(points - centre, axis=1).max())
