"""Robots as a bag describes them: each link's visuals, from its ``robot_description``.

A bag carries every robot's URDF (``/robot_description``, ``/R/robot_description``) with its
links named as their ``/tf`` frames: the root link is the robot's frame, link L is
``<robot>/L``. :func:`parse_robot` reads each link's ``<visual>`` elements: the geometry
(a mesh file with its scale, a box, a cylinder, a sphere), its origin in the link frame and
its material colour (inline or named at the robot's top level).

A mesh file is looked for, in turn: as named (an absolute path or ``file://`` URI, as the
machine that made the bag wrote it), in the ROS package of a ``package://`` URI, relative to
the robot's URDF file (a ``package://`` URI as PyBullet reads it: without its scheme; the
scenario in the bag names the URDF file, itself found as a mesh is), then by its trailing
path parts (``franka_panda/meshes/visual/link0.obj``, ``meshes/visual/link0.obj``,
...) in the given directories and the asset directories (:mod:`projection_server.assets`,
which include ``pybullet_data``): a bag made on another machine still finds the Panda's
meshes. A mesh not found, or of a format PyBullet cannot draw, becomes a small box and a
warning (once per file); it never stops a render.

The root's ``/tf`` frame is its centre of mass (PyBullet's base frame): its visuals are
placed through the inverse of the root link's inertial origin.
"""

from __future__ import annotations

from dataclasses import dataclass
import logging
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import unquote, urlparse
import xml.etree.ElementTree as ElementTree

import numpy as np

from projection_server import assets
from projection_server.render.scene import compose, RenderError

if TYPE_CHECKING:
    from collections.abc import Iterable, Mapping

__all__ = ['DEFAULT_COLOR', 'LinkVisual', 'MISSING_SIZE', 'RobotModel', 'find_mesh',
           'parse_robot']

log = logging.getLogger('projection_server.render')

DEFAULT_COLOR = (0.75, 0.75, 0.75, 1.0)   # a visual without a material
MISSING_SIZE = (0.04, 0.04, 0.04)         # the box drawn for a mesh not found
_DRAWABLE = frozenset({'.obj', '.stl'})   # mesh formats PyBullet's createVisualShape reads


@dataclass(frozen=True)
class LinkVisual:
    """One ``<visual>`` of a link: ``kind`` ``mesh``, ``box``, ``cylinder`` or ``sphere``;
    ``size`` the mesh's scale, the box's edges, the cylinder's (radius, radius, length)
    or the sphere's (r, r, r); ``xyz``/``quat`` its pose in the link's ``/tf`` frame;
    ``mesh`` the mesh file found (``kind`` is ``box`` if none was)."""

    frame: str
    kind: str
    size: tuple[float, float, float]
    xyz: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    rgba: tuple[float, float, float, float]
    mesh: str | None = None


@dataclass(frozen=True)
class RobotModel:
    """A robot's name (its root link's frame), its links' visuals, and the mesh files named
    in its URDF that were not found (drawn as boxes)."""

    name: str
    visuals: tuple[LinkVisual, ...]
    missing: tuple[str, ...] = ()


def parse_robot(urdf: str, topic: str = '/robot_description',
                search: Iterable[str | Path] = (),
                urdf_files: Mapping[str, str] | None = None) -> RobotModel:
    """The robot described by URDF text ``urdf`` (from bag topic ``topic``); mesh files
    are also looked for in the directories ``search``, and relative to the robot's URDF
    file in ``urdf_files`` (robot name -> the path the bag's maker had).

    Raises:
        RenderError: the text is not a URDF with links.
    """
    try:
        root = ElementTree.fromstring(urdf)
    except ElementTree.ParseError as exc:
        raise RenderError(f'{topic}: not a URDF: {exc}') from exc
    links = root.findall('link')
    if root.tag != 'robot' or not links:
        raise RenderError(f'{topic}: not a URDF robot with links')
    children = {child.get('link') for child in root.iter('child')}
    roots = [link for link in links if link.get('name') not in children]
    name = roots[0].get('name') if roots else links[0].get('name')
    colors: dict[str, tuple[float, float, float, float]] = {}
    for material in root.iter('material'):   # defined at the top or in a first visual
        if material.find('color') is not None:
            colors.setdefault(material.get('name', ''), _rgba(material))
    dirs = [str(d) for d in search] + assets.directories()
    urdf_file = (urdf_files or {}).get(name)
    found = find_mesh(urdf_file, dirs) if urdf_file else None
    base = str(Path(found).parent) if found is not None else None
    visuals: list[LinkVisual] = []
    missing: list[str] = []
    for link in links:
        frame = link.get('name', '')
        offset = (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
        if frame == name:
            # The root's /tf frame is its inertial frame: go back to the link frame.
            inertial = link.find('inertial/origin')
            if inertial is not None:
                offset = _inverse(*_origin(inertial))
        for visual in link.findall('visual'):
            geometry = visual.find('geometry')
            if geometry is None or len(geometry) == 0:
                continue
            xyz, quat = compose(*_origin(visual.find('origin')), *offset)
            material = visual.find('material')
            rgba = DEFAULT_COLOR
            if material is not None:
                rgba = (_rgba(material) if material.find('color') is not None
                        else colors.get(material.get('name'), DEFAULT_COLOR))
            kind, size, mesh = _geometry(geometry[0], dirs, base, missing)
            visuals.append(LinkVisual(frame, kind, size, tuple(map(float, xyz)),
                                      tuple(map(float, quat)), rgba, mesh))
    return RobotModel(name, tuple(visuals), tuple(missing))


def find_mesh(filename: str, dirs: Iterable[str], base: str | None = None) -> str | None:
    """The file that URDF ``filename`` names, found as described in the module's
    docstring (``base``: the URDF's directory, if known), or None."""
    parsed = urlparse(filename)
    if parsed.scheme == 'file':
        path = unquote(parsed.path)
    elif parsed.scheme == 'package':
        path = parsed.path.lstrip('/')
        try:
            from ament_index_python.packages import get_package_share_directory
            share = get_package_share_directory(parsed.netloc)
        except Exception:   # no ament index, or no such package: look by suffix
            share = None
        if share is not None and os.path.isfile(os.path.join(share, path)):
            return os.path.join(share, path)
        path = os.path.join(parsed.netloc, path)
    else:
        path = filename
    if os.path.isabs(path):
        if os.path.isfile(path):
            return path
    elif base is not None and os.path.isfile(os.path.join(base, path)):
        return os.path.join(base, path)
    parts = Path(path).parts
    parts = parts[1:] if parts and parts[0] == os.sep else parts
    dirs = ([base] if base is not None else []) + list(dirs)
    # Longest suffix first; a bare file name alone is too weak a match.
    for start in range(len(parts) - min(2, len(parts)) + 1):
        suffix = os.path.join(*parts[start:])
        for d in dirs:
            candidate = os.path.join(d, suffix)
            if os.path.isfile(candidate):
                return candidate
    return None


def _geometry(element: ElementTree.Element, dirs: list[str], base: str | None,
              missing: list[str]) -> tuple[str, tuple[float, float, float], str | None]:
    tag = element.tag
    if tag == 'box':
        return 'box', _floats(element.get('size'), 3, 0.0), None
    if tag == 'cylinder':
        r = float(element.get('radius', 0.0))
        return 'cylinder', (r, r, float(element.get('length', 0.0))), None
    if tag == 'sphere':
        r = float(element.get('radius', 0.0))
        return 'sphere', (r, r, r), None
    if tag == 'mesh':
        filename = element.get('filename', '')
        scale = _floats(element.get('scale'), 3, 1.0)
        found = find_mesh(filename, dirs, base) if filename else None
        if found is not None and Path(found).suffix.lower() in _DRAWABLE:
            return 'mesh', scale, found
        if filename not in missing:
            missing.append(filename)
            why = 'not found' if found is None else 'of a format that cannot be drawn'
            log.warning('mesh %s %s: its link is drawn as a small box', filename, why)
        return 'box', MISSING_SIZE, None
    return 'box', MISSING_SIZE, None


def _floats(text: str | None, n: int, default: float) -> tuple[float, ...]:
    values = [float(v) for v in (text or '').split()]
    if len(values) == 1 and n > 1:   # a uniform scale
        values = values * n
    return tuple(values) if len(values) == n else (default,) * n


def _rgba(material: ElementTree.Element) -> tuple[float, float, float, float]:
    color = material.find('color')
    values = _floats(color.get('rgba') if color is not None else None, 4, -1.0)
    return DEFAULT_COLOR if values[0] < 0 else values


def _origin(element: ElementTree.Element | None) -> tuple[np.ndarray, np.ndarray]:
    if element is None:
        return np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
    xyz = np.array(_floats(element.get('xyz'), 3, 0.0))
    roll, pitch, yaw = _floats(element.get('rpy'), 3, 0.0)
    return xyz, _quaternion_rpy(roll, pitch, yaw)


def _quaternion_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw (Rz(yaw) Ry(pitch) Rx(roll)) as (x, y, z, w)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy])


def _inverse(xyz: np.ndarray, quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    conj = np.array([-quat[0], -quat[1], -quat[2], quat[3]])
    moved, _ = compose(-xyz, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), conj)
    return moved, conj
