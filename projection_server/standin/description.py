"""A robot's URDF as robot_state_publisher reads it: its joints, their transforms, its text.

What the stand-in publishes of its robot comes from here, computed from the URDF and the
joint positions alone (no physics client), as robot_state_publisher computes it:

* :meth:`RobotTree.static_transforms`: each fixed joint, parent link -> child link;
* :meth:`RobotTree.transforms`: each moving joint at the given positions (a mimic joint
  follows its joint: ``multiplier * value + offset``);
* :attr:`RobotTree.state_joints`: the joints on ``/joint_states``, neither fixed nor mimic;
* :meth:`RobotTree.description`: the URDF with its mesh files named
  ``package://<package>/<path from the URDF's directory>``, which a reader resolves
  through its package index or its asset directories.

    >>> tree = RobotTree.from_file(panda_urdf)
    >>> tree.state_joints[-1], tree.root
    ('panda_finger_joint1', 'panda_link0')
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path
from typing import TYPE_CHECKING
import xml.etree.ElementTree as ET

import numpy as np

from projection_server.geometry import quaternion_of

if TYPE_CHECKING:
    from collections.abc import Mapping, Sequence

__all__ = ['Joint', 'RobotTree', 'Transform', 'matrix_of', 'pose_of']

# (parent frame, child frame, xyz, quaternion x y z w)
Transform = tuple[str, str, tuple[float, float, float], tuple[float, float, float, float]]


@dataclass(frozen=True)
class Joint:
    """A URDF joint: its kind, its links, its origin, its axis, whom it mimics."""

    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray            # 4x4, the child's frame in the parent's at value 0
    axis: np.ndarray
    limits: tuple[float, float]   # (lower, upper); (0, 0) when the URDF gives none
    mimic: tuple[str, float, float] | None = None   # (joint, multiplier, offset)

    @property
    def moves(self) -> bool:
        return self.kind != 'fixed'

    def at(self, value: float) -> np.ndarray:
        """The child's frame in the parent's at joint value ``value``."""
        if self.kind in ('revolute', 'continuous'):
            return self.origin @ _rotation(self.axis, value)
        if self.kind == 'prismatic':
            motion = np.eye(4)
            motion[:3, 3] = self.axis * value
            return self.origin @ motion
        return self.origin


class RobotTree:
    """The joints of a URDF, parents before children."""

    def __init__(self, path: Path, root: ET.Element):
        self.path = path
        self._xml = root
        self.name: str = root.get('name', '') or path.stem
        joints = [_joint(element) for element in root.findall('joint')]
        children = {j.child for j in joints}
        roots = [link.get('name') for link in root.findall('link')
                 if link.get('name') not in children]
        if len(roots) != 1:
            raise ValueError(f'{path}: a robot has one root link, this one {roots}')
        self.root: str = roots[0]
        by_parent: dict[str, list[Joint]] = {}
        for joint in joints:
            by_parent.setdefault(joint.parent, []).append(joint)
        ordered, todo = [], [self.root]
        while todo:   # breadth first: a joint's parent link is placed before it
            link = todo.pop(0)
            for joint in by_parent.get(link, []):
                ordered.append(joint)
                todo.append(joint.child)
        self.joints: list[Joint] = ordered
        self.state_joints: list[str] = [j.name for j in ordered if j.moves and j.mimic is None]

    @classmethod
    def from_file(cls, path: str | Path) -> RobotTree:
        path = Path(path)
        return cls(path, ET.parse(path).getroot())

    def joint(self, name: str) -> Joint:
        return next(j for j in self.joints if j.name == name)

    def values(self, positions: Mapping[str, float]) -> dict[str, float]:
        """The value of every moving joint: ``positions``' (0 for one not given), and each
        mimic joint's from the joint it follows."""
        values = {j.name: float(positions.get(j.name, 0.0)) for j in self.joints
                  if j.moves and j.mimic is None}
        for j in self.joints:
            if j.mimic is not None:
                followed, multiplier, offset = j.mimic
                values[j.name] = multiplier * values.get(followed, 0.0) + offset
        return values

    def static_transforms(self) -> list[Transform]:
        """Parent link -> child link of each fixed joint (``/tf_static``)."""
        return [(j.parent, j.child, *pose_of(j.origin)) for j in self.joints if not j.moves]

    def transforms(self, positions: Mapping[str, float]) -> list[Transform]:
        """Parent link -> child link of each moving joint at ``positions`` (``/tf``)."""
        values = self.values(positions)
        return [(j.parent, j.child, *pose_of(j.at(values[j.name])))
                for j in self.joints if j.moves]

    def link_frames(self, base: np.ndarray, positions: Mapping[str, float]
                    ) -> dict[str, np.ndarray]:
        """Every link's frame in the world (4x4), the root link's being ``base``."""
        values = self.values(positions)
        frames = {self.root: base}
        for j in self.joints:
            frames[j.child] = frames[j.parent] @ j.at(values.get(j.name, 0.0))
        return frames

    def description(self, package: str | None = None) -> str:
        """The URDF's text, each mesh file ``package://<package>/<path>`` (``package``
        default: the name of the URDF's directory), its path from that directory."""
        package = package or self.path.parent.name
        root = ET.fromstring(ET.tostring(self._xml))
        for mesh in root.iter('mesh'):
            filename = mesh.get('filename', '')
            if filename:
                mesh.set('filename', f'package://{package}/{self._relative(filename)}')
        return ET.tostring(root, encoding='unicode')

    def _relative(self, filename: str) -> str:
        """A mesh file's path from the URDF's directory (``package://meshes/a.obj``, as
        pybullet_data names them, is ``meshes/a.obj`` there)."""
        for prefix in ('package://', 'file://'):
            if filename.startswith(prefix):
                filename = filename[len(prefix):]
        path = Path(filename)
        if path.is_absolute():
            try:
                return path.resolve().relative_to(self.path.parent.resolve()).as_posix()
            except ValueError:
                return path.name
        return path.as_posix()


def matrix_of(xyz: Sequence[float], quaternion: Sequence[float]) -> np.ndarray:
    """The 4x4 transform of a position and a quaternion (x, y, z, w)."""
    x, y, z, w = quaternion
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m[:3, 3] = xyz
    return m


def pose_of(m: np.ndarray) -> tuple[tuple[float, float, float],
                                    tuple[float, float, float, float]]:
    """Position and quaternion (x, y, z, w) of a 4x4 transform."""
    return (tuple(float(v) for v in m[:3, 3]),
            tuple(float(v) for v in quaternion_of(m[:3, :3])))


def _joint(element: ET.Element) -> Joint:
    origin = element.find('origin')
    xyz = _floats(origin.get('xyz') if origin is not None else None, 3)
    rpy = _floats(origin.get('rpy') if origin is not None else None, 3)
    frame = _rpy(*rpy)
    frame[:3, 3] = xyz
    axis_element = element.find('axis')
    axis = np.asarray(_floats(axis_element.get('xyz') if axis_element is not None else None,
                              3, default=(1.0, 0.0, 0.0)))
    if np.linalg.norm(axis) > 0:
        axis = axis / np.linalg.norm(axis)
    limit = element.find('limit')
    limits = ((float(limit.get('lower', 0.0)), float(limit.get('upper', 0.0)))
              if limit is not None else (0.0, 0.0))
    mimic_element = element.find('mimic')
    mimic = None
    if mimic_element is not None:
        mimic = (mimic_element.get('joint'), float(mimic_element.get('multiplier', 1.0)),
                 float(mimic_element.get('offset', 0.0)))
    return Joint(element.get('name'), element.get('type'), element.find('parent').get('link'),
                 element.find('child').get('link'), frame, axis, limits, mimic)


def _floats(text: str | None, size: int, default: Sequence[float] | None = None
            ) -> tuple[float, ...]:
    if not text:
        return tuple(default) if default is not None else (0.0,) * size
    return tuple(float(v) for v in text.split())


def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    return m


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the unit ``axis`` (Rodrigues)."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    t = 1 - c
    m = np.eye(4)
    m[:3, :3] = [[t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                 [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                 [t * x * z - s * y, t * y * z + s * x, t * z * z + c]]
    return m
