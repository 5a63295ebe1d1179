"""A robot description received as URDF text: parsed, its meshes resolved, written as a
model file the simulator loads.

Mesh names resolve as ROS tools resolve them, then as this package's model files do:

* ``package://PKG/PATH``: ``share/PKG/PATH`` of the ament index (``AMENT_PREFIX_PATH``),
  else ``PKG/PATH`` in the asset directories (``pybullet_data`` has ``franka_panda/``);
* ``file:///ABS`` and absolute paths: themselves;
* a relative path: in the asset directories.

The file found must lie in a package's share directory or an asset directory; one that is
not found is an error naming the URI. The description is written, its mesh names replaced
by the files found, to :func:`projection_server.assets.descriptions_dir` under its content
hash, so that a scenario names it like any model file and a projection made from it can be
run again later, without the robot.
"""

from __future__ import annotations

from dataclasses import dataclass
import hashlib
import math
import os
from pathlib import Path
import xml.etree.ElementTree as ElementTree

from projection_server import assets
from projection_server.world.errors import GraphError

__all__ = ['DescriptionError', 'Joint', 'RobotDescription', 'parse', 'write']


class DescriptionError(GraphError):
    """A robot description that cannot be used; :attr:`kind` is ``malformed``,
    ``mesh_missing`` or ``mesh_outside``, :attr:`culprit` the topic or URI."""

    @property
    def culprit(self) -> str:
        return self.subject


@dataclass(frozen=True)
class Joint:
    """A URDF joint: its type, limits (None: unlimited), the joint it mimics."""

    name: str
    type: str
    parent: str
    child: str
    lower: float | None
    upper: float | None
    mimic: str | None


@dataclass(frozen=True)
class RobotDescription:
    """A parsed URDF: its robot name, root link, joints and its text's SHA-256."""

    name: str
    root_link: str
    joints: dict[str, Joint]
    text: str
    sha256: str

    def moving_joints(self) -> list[str]:
        """The joints whose positions are the robot's state: not fixed, not mimicking."""
        return [j.name for j in self.joints.values()
                if j.type not in ('fixed', 'floating', 'planar') and j.mimic is None]


def parse(text: str, topic: str = '/robot_description') -> RobotDescription:
    """The robot described by the URDF ``text`` received on ``topic``.

    Raises:
        DescriptionError: ``malformed``, naming the line and column of a parse error, or
            what the URDF lacks.
    """
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        line, column = exc.position
        raise DescriptionError('malformed', topic, (
            f'the robot description on {topic} is not well formed XML: line {line}, '
            f'column {column}: {str(exc).split(":")[0]}')) from None
    if root.tag != 'robot':
        raise DescriptionError('malformed', topic, (
            f'the robot description on {topic} is no URDF: its root element is '
            f'<{root.tag}>, not <robot>'))
    links = [link.get('name') for link in root.findall('link')]
    if not links:
        raise DescriptionError('malformed', topic, f'the URDF on {topic} has no <link>')
    joints: dict[str, Joint] = {}
    for j in root.findall('joint'):
        parent, child, limit = j.find('parent'), j.find('child'), j.find('limit')
        if parent is None or child is None or not j.get('name'):
            raise DescriptionError('malformed', topic, (
                f'the URDF on {topic} has a joint without a name, parent or child '
                f'({j.get("name")!r})'))
        kind = j.get('type', '')
        lower = upper = None
        if limit is not None and kind in ('revolute', 'prismatic'):
            lower, upper = float(limit.get('lower', 0.0)), float(limit.get('upper', 0.0))
        mimic = j.find('mimic')
        joints[j.get('name')] = Joint(j.get('name'), kind, parent.get('link'),
                                      child.get('link'), lower, upper,
                                      mimic.get('joint') if mimic is not None else None)
    children = {j.child for j in joints.values()}
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise DescriptionError('malformed', topic, (
            f'the URDF on {topic} is not one tree of links: its roots are '
            f'{", ".join(roots) or "none"}'))
    return RobotDescription(root.get('name', ''), roots[0], joints, text,
                            hashlib.sha256(text.encode()).hexdigest())


def _ament_share(package: str) -> str | None:
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix and os.path.isfile(os.path.join(prefix, 'share', 'ament_index',
                                                  'resource_index', 'packages', package)):
            return os.path.join(prefix, 'share', package)
    return None


def resolve_mesh(uri: str) -> str:
    """The file the mesh name ``uri`` of a received URDF stands for (see the module).

    Raises:
        DescriptionError: ``mesh_missing`` (where it was looked for), ``mesh_outside``.
    """
    dirs = assets.directories()
    if uri.startswith('package://'):
        package, _, rest = uri[len('package://'):].partition('/')
        share = _ament_share(package)
        candidates = ([os.path.join(share, rest)] if share else []) + [
            os.path.join(d, package, rest) for d in dirs]
        where = (f'share/{package} of the ament index ' if share else
                 f'no package {package} in the ament index; ') + 'and the asset directories'
    elif uri.startswith('file://') or os.path.isabs(uri):
        candidates, where = [uri.removeprefix('file://')], 'that path'
    else:
        candidates, where = [os.path.join(d, uri) for d in dirs], 'the asset directories'
    for candidate in candidates:
        real = os.path.realpath(candidate)
        if os.path.isfile(real):
            if not assets.inside_model_roots(real):
                raise DescriptionError('mesh_outside', uri, (
                    f'the mesh {uri} of the robot description is {real}, outside the '
                    'asset directories and the packages\' share directories'))
            return real
    raise DescriptionError('mesh_missing', uri, (
        f'the mesh {uri} of the robot description was not found (looked in {where})'))


def write(description: RobotDescription) -> str:
    """Write ``description`` with its meshes resolved as a model file; its path.

    Raises:
        DescriptionError: a mesh not found, or outside the allowed directories.
    """
    root = ElementTree.fromstring(description.text)
    for mesh in root.iter('mesh'):
        mesh.set('filename', resolve_mesh(mesh.get('filename', '')))
    text = ElementTree.tostring(root, encoding='unicode')
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    name = ''.join(c if c.isalnum() or c in '-_' else '_' for c in description.name) or 'robot'
    path = Path(assets.descriptions_dir()) / f'{name}-{digest}.urdf'
    if not path.exists():   # content-addressed: a file there already is this one
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f'.{os.getpid()}.tmp')
        tmp.write_text(text)
        os.replace(tmp, path)
    return str(path)


def within_limits(joint: Joint, position: float, tolerance: float = 1e-3) -> bool:
    """Whether ``position`` is within ``joint``'s limits (a little slack for sensor noise)."""
    if joint.lower is None or joint.upper is None or joint.upper < joint.lower:
        return math.isfinite(position)
    return joint.lower - tolerance <= position <= joint.upper + tolerance
