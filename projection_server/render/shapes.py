"""PyBullet visual shapes of markers and of robots' link visuals, in a render client."""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

    from projection_server.render.robots import LinkVisual
    from projection_server.render.scene import Shape

__all__ = ['link_visual_shape', 'marker_visual_shape']

# visualization_msgs/Marker types
_CUBE, _SPHERE, _CYLINDER = 1, 2, 3
_CUBE_LIST, _SPHERE_LIST, _POINTS = 6, 7, 8
_TRIANGLE_LIST = 11


def marker_visual_shape(client: Any, shape: Shape, rgba: Sequence[float]) -> int:
    """A visual shape of marker ``shape`` in colour ``rgba``; -1 for markers not drawn
    (arrows, lines, text, meshes by resource)."""
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
        return -1
    return _mesh(client, vertices, normals, indices, rgba)


def link_visual_shape(client: Any, visual: LinkVisual) -> int:
    """A visual shape of a robot link's ``<visual>``; -1 if PyBullet refuses it."""
    import pybullet

    rgba = list(visual.rgba)
    a, b, c = visual.size
    try:
        if visual.kind == 'mesh':
            return client.createVisualShape(pybullet.GEOM_MESH, fileName=visual.mesh,
                                            meshScale=list(visual.size), rgbaColor=rgba)
        if visual.kind == 'sphere':
            return _mesh(client, *_ellipsoid(a, b, c), rgba)
        if visual.kind == 'cylinder':
            return _mesh(client, *_cylinder(a, b, c), rgba)
        return client.createVisualShape(pybullet.GEOM_BOX,
                                        halfExtents=[a / 2, b / 2, c / 2], rgbaColor=rgba)
    except pybullet.error:
        return -1


def _mesh(client: Any, vertices: np.ndarray, normals: np.ndarray, indices: np.ndarray,
          rgba: Sequence[float]) -> int:
    import pybullet

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
