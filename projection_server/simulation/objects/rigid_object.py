"""``rigid_object``: a rigid body of any shape, with the mass, friction and restitution of
its properties; breakable if it has a ``breaking_force``.

Its ``shape`` says what it is and which properties give its geometry (no others may be
given):

* ``box`` (``size_x``, ``size_y``, ``size_z``), ``cylinder`` (``radius``, ``height`` along
  z), ``sphere`` (``radius``): centred on the pose;
* ``mesh`` (``file``, an OBJ or STL file; ``scale``, default 1): the mesh's origin at the
  pose. A moving mesh (``mass`` > 0) collides as its convex decomposition (PyBullet's
  V-HACD), made once per file content and kept in a cache directory
  (:func:`convex_decomposition`); its centre of mass is the centroid of its volume. A static
  mesh (``mass`` 0) collides as its triangles, concave as it is;
* ``urdf`` (``file``, a URDF; ``scale``, its ``globalScaling``): loaded with its base link's
  frame at the pose. ``mass``, if given, is the total mass, shared among the links in the
  URDF's proportions (all on the base if the URDF gives none); 0 fixes the base; absent,
  the URDF's masses hold. ``friction``, ``restitution``, ``rolling_friction`` and
  ``spinning_friction`` replace the URDF's on every link. Joints are passive (no motors).

``mass`` is required but for a URDF; 0 makes the body static. A file is an absolute path
inside the asset directories (:mod:`projection_server.assets`; Prolog resolves the paths
a query gives). The pose of a moving body in ``/tf`` is PyBullet's base frame: its centre
of mass (a URDF's base inertial frame). Its marker is a box: the shape itself for a box,
a cylinder or a sphere as such; for a mesh its bounding box, for a URDF each link's
bounding box when spawned.

With a ``breaking_force`` the object breaks as the egg does, by the criterion of
:class:`~projection_server.simulation.object_models.Breakable`, each contact's load being
its normal force (:class:`~projection_server.simulation.object_models.RigidBreakable`). A
broken rigid object stays where it is as its own remains, reported broken, and no robot
holds it any more: its collisions with every robot's links are off.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import hashlib
import os
from pathlib import Path
import sys
import tempfile
import threading
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server import assets
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.object_models import RigidBreakable
from projection_server.simulation.objects.common import (lift_clear, orientation,
                                                        release_from_robots)
from projection_server.simulation.objects.registry import (FILE, FRACTION, NAME,
                                                           NONNEGATIVE, ObjectClass,
                                                           POSITIVE, Property, register,
                                                           REQUIRED)
from projection_server.simulation.physics import Body, Shape

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['RIGID_OBJECT', 'SHAPES', 'cache_dir', 'convex_decomposition']

# The properties that give each shape's geometry (required), and those it may have.
SHAPES = {'box': ('size_x', 'size_y', 'size_z'), 'cylinder': ('radius', 'height'),
          'sphere': ('radius',), 'mesh': ('file',), 'urdf': ('file',)}
_OPTIONAL = {'mesh': ('scale',), 'urdf': ('scale',)}
_GEOMETRY = frozenset({'size_x', 'size_y', 'size_z', 'radius', 'height', 'file', 'scale'})
_SUFFIXES = {'mesh': ('.obj', '.stl'), 'urdf': ('.urdf',)}

COLOR = (0.55, 0.65, 0.8, 1.0)
# V-HACD's settings (pybullet.vhacd's defaults, written out: they are part of the cache key).
VHACD = {'resolution': 100000, 'depth': 20, 'concavity': 0.0025, 'planeDownsampling': 4,
         'convexhullDownsampling': 4, 'alpha': 0.05, 'beta': 0.05, 'gamma': 0.00125,
         'pca': 0, 'mode': 0, 'maxNumVerticesPerCH': 64, 'minVolumePerCH': 0.0001}
_decomposing = threading.Lock()


def build(physics: Physics, entity: Entity) -> None:
    shape = entity.properties['shape']
    if shape == 'urdf':
        body = _urdf(physics, entity)
    elif shape == 'mesh':
        body = _mesh(physics, entity)
    else:
        body = _primitive(physics, entity)
    breaking_force = entity.properties.get('breaking_force')
    if breaking_force is not None:
        physics.models.append(RigidBreakable(entity.name, breaking_force, _remains))
    if not body.static:
        lift_clear(physics, body.body_id)


def _remains(physics: Physics, name: str) -> None:
    """A broken rigid object stays as its remains, which no robot holds."""
    release_from_robots(physics, physics.body(name).body_id)


def _dynamics(c: Any, body: int, link: int, p: dict[str, Any]) -> None:
    c.changeDynamics(body, link, lateralFriction=p['friction'], restitution=p['restitution'],
                     rollingFriction=p['rolling_friction'],
                     spinningFriction=p['spinning_friction'])


def _primitive(physics: Physics, entity: Entity) -> Body:
    c, p = physics.client, entity.properties
    if p['shape'] == 'box':
        size = (p['size_x'], p['size_y'], p['size_z'])
        shape = c.createCollisionShape(c.GEOM_BOX, halfExtents=[s / 2 for s in size])
    elif p['shape'] == 'cylinder':
        size = (2 * p['radius'], 2 * p['radius'], p['height'])
        shape = c.createCollisionShape(c.GEOM_CYLINDER, radius=p['radius'], height=p['height'])
    else:
        size = (2 * p['radius'],) * 3
        shape = c.createCollisionShape(c.GEOM_SPHERE, radius=p['radius'])
    body = c.createMultiBody(p['mass'], shape, -1, entity.pose.xyz, orientation(c, entity))
    _dynamics(c, body, -1, p)
    return physics.add_body(Body(entity.name, entity.cls, body, p['mass'] == 0.0,
                                 Shape(p['shape'], size, COLOR)))


def _mesh(physics: Physics, entity: Entity) -> Body:
    c, p = physics.client, entity.properties
    path, scale, mass = p['file'], p.get('scale', 1.0), p['mass']
    mesh = assets.read_mesh(path)
    vertices = np.asarray(mesh.vertices, dtype=float) * scale
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    if mass > 0.0:
        centre = _centroid(vertices, np.asarray(mesh.triangles, dtype=int), low, high)
        options = {'fileName': convex_decomposition(path)}
    else:
        centre = np.zeros(3)
        options = {'fileName': path, 'flags': c.GEOM_FORCE_CONCAVE_TRIMESH}
    try:
        shape = c.createCollisionShape(c.GEOM_MESH, meshScale=[scale] * 3, **options)
    except Exception as exc:   # pybullet.error
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: PyBullet cannot load {path}: {exc}') from None
    body = c.createMultiBody(mass, shape, -1, entity.pose.xyz, orientation(c, entity),
                             baseInertialFramePosition=centre.tolist())
    _dynamics(c, body, -1, p)
    box = Shape('box', tuple(np.maximum(high - low, 1e-4)), COLOR)
    return physics.add_body(Body(entity.name, entity.cls, body, mass == 0.0, None,
                                 link_shapes={-1: [(box, tuple(((low + high) / 2 - centre)
                                                               .tolist()))]}))


def _centroid(vertices: np.ndarray, triangles: np.ndarray, low: np.ndarray,
              high: np.ndarray) -> np.ndarray:
    """The centroid of the volume a closed mesh encloses; the bounding box's centre for a
    mesh that encloses none (open, or not consistently oriented)."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    volumes = np.einsum('ij,ij->i', a, np.cross(b, c)) / 6.0
    volume = volumes.sum()
    if abs(volume) > 1e-12:
        centre = (volumes[:, None] * (a + b + c)).sum(axis=0) / (4.0 * volume)
        if np.all(centre >= low) and np.all(centre <= high):
            return centre
    return (low + high) / 2


def _urdf(physics: Physics, entity: Entity) -> Body:
    c, p = physics.client, entity.properties
    mass = p.get('mass')
    try:
        body = c.loadURDF(p['file'], entity.pose.xyz, orientation(c, entity),
                          useFixedBase=mass == 0.0, globalScaling=p.get('scale', 1.0))
    except Exception as exc:   # pybullet.error
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: PyBullet cannot load {p["file"]}: {exc}') from None
    joints = c.getNumJoints(body)
    links = {j: c.getJointInfo(body, j)[12].decode() for j in range(joints)}
    for j in range(joints):   # passive joints: PyBullet motorises them by default
        if c.getJointInfo(body, j)[2] in (c.JOINT_REVOLUTE, c.JOINT_PRISMATIC):
            c.setJointMotorControl2(body, j, c.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0)
    if mass is not None and mass > 0.0:
        masses = [c.getDynamicsInfo(body, link)[0] for link in range(-1, joints)]
        total = sum(masses)
        for link, share in zip(range(-1, joints), masses):
            if total > 0.0:
                c.changeDynamics(body, link, mass=share * mass / total)
            elif link == -1:
                c.changeDynamics(body, link, mass=mass)
    for link in range(-1, joints):
        _dynamics(c, body, link, p)
    static = joints == 0 and c.getDynamicsInfo(body, -1)[0] == 0.0
    return physics.add_body(Body(entity.name, entity.cls, body, static, None, links=links,
                                 link_shapes=_link_boxes(c, body, joints)))


def _link_boxes(c: Any, body: int, joints: int
                ) -> dict[int, list[tuple[Shape, tuple[float, float, float]]]]:
    """Each link's bounding box now, in its frame as ``/tf`` logs it (a link's URDF frame,
    the base's centre of mass)."""
    boxes = {}
    for link in range(-1, joints):
        low, high = (np.asarray(v) for v in c.getAABB(body, link))
        if not np.all(high > low):
            continue
        if link == -1:
            position, quaternion = c.getBasePositionAndOrientation(body)
        else:
            position, quaternion = c.getLinkState(body, link, computeForwardKinematics=True)[4:6]
        inverse = c.invertTransform(position, quaternion)
        offset, turn = c.multiplyTransforms(*inverse, ((low + high) / 2).tolist(),
                                            (0.0, 0.0, 0.0, 1.0))
        boxes[link] = [(Shape('box', tuple(high - low), COLOR, turn), tuple(offset))]
    return boxes


# --- convex decomposition -------------------------------------------------------------------

def cache_dir() -> Path:
    """Where convex decompositions are kept: ``$PROJECTION_SERVER_CACHE/vhacd``, else
    ``~/.cache/projection_server/vhacd``."""
    root = os.environ.get('PROJECTION_SERVER_CACHE')
    base = Path(root).expanduser() if root else Path.home() / '.cache' / 'projection_server'
    return base / 'vhacd'


def convex_decomposition(path: str) -> str:
    """The path of the convex decomposition (an OBJ of convex parts) of the mesh at
    ``path``, made with PyBullet's V-HACD once per content of the file and kept in
    :func:`cache_dir`.

    The decomposition is of the mesh as written: a body scales it (V-HACD's parts scale
    with the mesh), so one decomposition serves every ``scale``. It is written under a
    name of its own and renamed into place, so processes that make it at once each find a
    whole file.
    """
    mesh = assets.read_mesh(path)
    text = _obj_text(mesh)
    key = hashlib.sha256(repr((sorted(VHACD.items()), text)).encode()).hexdigest()
    directory = cache_dir()
    target = directory / f'{key}.obj'
    if target.is_file():
        return str(target)
    with _decomposing:
        if target.is_file():
            return str(target)
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=directory, prefix='.vhacd-') as tmp:
            source, result = Path(tmp) / 'mesh.obj', Path(tmp) / 'parts.obj'
            source.write_text(text)
            _vhacd(str(source), str(result), str(Path(tmp) / 'vhacd.log'))
            if not result.is_file() or result.stat().st_size == 0:
                raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                      f'V-HACD made no convex decomposition of {path}')
            os.replace(result, target)
    return str(target)


def _obj_text(mesh: assets.Mesh) -> str:
    """The mesh as a plain OBJ (what V-HACD reads, whatever the file's format was)."""
    lines = [f'v {x!r} {y!r} {z!r}' for x, y, z in mesh.vertices]
    lines += [f'f {a + 1} {b + 1} {c + 1}' for a, b, c in mesh.triangles]
    return '\n'.join(lines) + '\n'


def _vhacd(source: str, result: str, log: str) -> None:
    """pybullet.vhacd (a function of the module, no physics client), its progress printed
    to ``log`` instead of the process's standard output."""
    import pybullet

    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(log, 'ab') as sink:
            os.dup2(sink.fileno(), 1)
            try:
                pybullet.vhacd(source, result, log, **VHACD)
            finally:
                _libc().fflush(None)
    finally:
        os.dup2(saved, 1)
        os.close(saved)


@functools.cache
def _libc() -> Any:
    return ctypes.CDLL(ctypes.util.find_library('c'))


def _check(name: str, values: dict[str, Any]) -> None:
    shape = values['shape']
    if shape not in SHAPES:
        _fail(f'{name}: unknown shape {shape!r} (known: {", ".join(SHAPES)})')
    missing = [key for key in SHAPES[shape] if key not in values]
    if missing:
        _fail(f'{name}: a {shape} needs {" and ".join(missing)}')
    other = sorted(_GEOMETRY & set(values) - set(SHAPES[shape]) - set(_OPTIONAL.get(shape, ())))
    if other:
        _fail(f'{name}: {", ".join(other)} is not a property of a {shape} (a {shape} has '
              f'{", ".join(SHAPES[shape] + _OPTIONAL.get(shape, ()))})')
    if 'mass' not in values and shape != 'urdf':
        _fail(f'{name}: a {shape} needs a mass (0: static)')
    if shape in _SUFFIXES and not values['file'].lower().endswith(_SUFFIXES[shape]):
        _fail(f'{name}: the file of a {shape} is a {" or ".join(_SUFFIXES[shape])} file, '
              f'not {values["file"]!r}')


def _fail(message: str):
    raise ProjectionError(ErrorKind.INVALID_SCENARIO, message)


RIGID_OBJECT = register(ObjectClass(
    name='rigid_object',
    properties=(Property('shape', REQUIRED, NAME, '', ', '.join(SHAPES)),
                Property('size_x', None, POSITIVE, 'm', 'box'),
                Property('size_y', None, POSITIVE, 'm', 'box'),
                Property('size_z', None, POSITIVE, 'm', 'box'),
                Property('radius', None, POSITIVE, 'm', 'cylinder, sphere'),
                Property('height', None, POSITIVE, 'm', 'cylinder, along z'),
                Property('file', None, FILE, '', 'mesh (OBJ, STL), urdf'),
                Property('scale', None, POSITIVE, '', 'mesh, urdf: uniform; default 1'),
                Property('mass', None, NONNEGATIVE, 'kg',
                         '0: static; required but for a urdf (absent: its own masses)'),
                Property('friction', 0.5, NONNEGATIVE),
                Property('restitution', 0.1, FRACTION),
                Property('rolling_friction', 0.0, NONNEGATIVE, 'm'),
                Property('spinning_friction', 0.0, NONNEGATIVE, 'm'),
                Property('breaking_force', None, POSITIVE, 'N',
                         'breaks at this load (each contact: its normal force); absent: '
                         'never')),
    build=build,
    check=_check,
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
