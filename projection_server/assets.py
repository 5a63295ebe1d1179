"""Model files of scenario entities: where they resolve, whether they are well formed, and
what they hold (for cache keys).

A model file (a URDF, an SDF, an OBJ or an STL mesh) is named by an entity's file-valued
property (``file`` of a ``rigid_object``; a ``urdf`` robot's may be an SDF). It resolves
only inside the *asset directories*: the package's own (:data:`PACKAGE_ASSETS`), the
directories the node is configured with (parameter ``asset_paths``), ``pybullet_data``'s and
the one where robot descriptions received over ROS are written (:func:`descriptions_dir`),
in that order, each taken with its symbolic links and ``..`` resolved (:func:`configure`,
:func:`directories`):

* a relative path is looked up in each directory in turn; the first that has it wins;
* an absolute path must lie inside one of them;
* either way, the file found must lie inside one of them once its own symbolic links and
  ``..`` are resolved (a link out of a directory does not lead out of the sandbox).

Prolog resolves every file of a scenario when the entity is added or changed
(``prolog/model_files.pl``, through :func:`resolve`), so that the scenario description
holds the absolute path; a job checks its files again (:func:`checked`), since jobs may
come from any client.

A file's content is checked once per (path, modification time, size): a URDF must be XML
with a ``<robot>`` of at least one ``<link>``, an SDF XML with an ``<sdf>`` holding a
``<model>`` of at least one ``<link>`` (a mesh ``<uri>`` is relative to the SDF's directory,
with or without a leading ``/``, as PyBullet takes it), and every mesh either names must
resolve inside the asset directories or a package's share directory of the ament index, as
``package://`` names it (and be well formed, for OBJ and STL); an OBJ must
have vertices and faces whose indices exist; an STL must be binary with a length that
matches its triangle count, or ASCII (``solid`` ... ``facet`` ... ``vertex``).
:func:`digest` is the content hash of a file and the meshes a URDF or SDF names: it is part
of a projection's cache key.

Pure standard library: Prolog imports it also where no simulator is installed.
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path
import struct
import threading
from typing import Iterable, NamedTuple
import xml.etree.ElementTree as ElementTree

from projection_server.errors import ErrorKind, ProjectionError

__all__ = [
    'FORMATS',
    'Mesh',
    'PACKAGE_ASSETS',
    'checked',
    'configure',
    'default_directories',
    'descriptions_dir',
    'digest',
    'directories',
    'inside_model_roots',
    'problem',
    'read_mesh',
    'resolve',
]

PACKAGE_ASSETS = Path(__file__).resolve().parent / 'simulation' / 'objects' / 'assets'
FORMATS = {'.urdf': 'urdf', '.sdf': 'sdf', '.obj': 'obj', '.stl': 'stl'}

_FORMATS_MESSAGE = 'a model file is a .urdf, .sdf, .obj or .stl file'
_lock = threading.Lock()
_configured: tuple[str, ...] | None = None


class Mesh(NamedTuple):
    """A triangle mesh as read from a file: vertices ``(x, y, z)`` and triangles (vertex
    index triples, from 0)."""

    vertices: list[tuple[float, float, float]]
    triangles: list[tuple[int, int, int]]


class _Malformed(Exception):
    """What is wrong with a file's content."""


# --- the asset directories --------------------------------------------------------------

def descriptions_dir() -> str:
    """Where robot descriptions received over ROS are written as model files
    (:mod:`projection_server.world.description`): ``$PROJECTION_SERVER_DESCRIPTIONS``,
    else ``~/.cache/projection_server/robot_descriptions``."""
    return os.environ.get('PROJECTION_SERVER_DESCRIPTIONS') or os.path.join(
        os.path.expanduser('~'), '.cache', 'projection_server', 'robot_descriptions')


def default_directories(user: Iterable[str] = ()) -> list[str]:
    """The package's asset directory, ``user``'s, ``pybullet_data``'s (if installed) and
    :func:`descriptions_dir`, in that order, resolved, each once."""
    dirs = [str(PACKAGE_ASSETS), *user]
    try:
        import pybullet_data
    except ImportError:   # Prolog's own tests run where no simulator is installed
        pass
    else:
        dirs.append(pybullet_data.getDataPath())
    dirs.append(descriptions_dir())   # last: no relative path of a user's resolves there
    out: list[str] = []
    for d in dirs:
        real = os.path.realpath(os.path.expanduser(str(d)))
        if real not in out:
            out.append(real)
    return out


def configure(user: Iterable[str]) -> list[str]:
    """Make the asset directories those of :func:`default_directories` with ``user``'s;
    return them.

    Raises:
        ValueError: a user directory that is not a directory.
    """
    global _configured
    user = [str(d) for d in user]
    for d in user:
        if not os.path.isdir(os.path.expanduser(d)):
            raise ValueError(f'asset directory {d!r} is not a directory')
    with _lock:
        _configured = tuple(default_directories(user))
        return list(_configured)


def directories() -> list[str]:
    """The asset directories: as configured, else :func:`default_directories`."""
    with _lock:
        configured = _configured
    return list(configured) if configured is not None else default_directories()


# --- resolving ----------------------------------------------------------------------------

def resolve(path: str, dirs: Iterable[str] | None = None) -> list[str]:
    """Where ``path`` resolves among ``dirs`` (default: :func:`directories`), and whether
    the file there is well formed, as ``[status, value, message]``:

    * ``['ok', absolute path, '']``;
    * ``['outside', path, message]``: it resolves outside every directory;
    * ``['missing', path, message]``: no directory has it;
    * ``['format', path, message]``: not a ``.urdf``, ``.sdf``, ``.obj`` or ``.stl`` file;
    * ``['malformed', format, message]``: its content is not a well formed model.
    """
    dirs = tuple(dirs) if dirs is not None else tuple(directories())
    listed = ', '.join(dirs)
    found = _locate(str(path), dirs)
    if found is None:
        return ['outside', path, f'it resolves outside the asset directories ({listed})']
    if not os.path.isfile(found):
        return ['missing', path, f'no such file in the asset directories ({listed})']
    fmt = FORMATS.get(os.path.splitext(found)[1].lower())
    if fmt is None:
        return ['format', path, _FORMATS_MESSAGE]
    message = problem(found, dirs)
    if message is not None:
        return ['malformed', fmt, message]
    return ['ok', found, '']


def checked(path: str, dirs: Iterable[str] | None = None) -> str:
    """The content digest of the model file ``path`` of a job, which must be absolute,
    inside the asset directories (default: :func:`directories`) and well formed.

    Raises:
        ProjectionError: kind ``invalid_scenario``, naming the file and what is wrong.
    """
    if not isinstance(path, str) or not os.path.isabs(path):
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'model file {path!r} is not an absolute path')
    dirs = tuple(dirs) if dirs is not None else tuple(directories())
    status, value, message = resolve(path, dirs)
    if status != 'ok':
        raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'model file {path}: {message}')
    return digest(value, dirs)


def _inside(real: str, dirs: Iterable[str]) -> bool:
    return any(real == d or real.startswith(d.rstrip(os.sep) + os.sep) for d in dirs)


def _package_shares() -> tuple[str, ...]:
    """The ``share`` directories of the ament index's prefixes (``AMENT_PREFIX_PATH``),
    where ``package://`` meshes live."""
    return tuple(os.path.realpath(os.path.join(p, 'share'))
                 for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p)


def inside_model_roots(real: str, dirs: Iterable[str] | None = None) -> bool:
    """Whether the resolved path ``real`` may be read as a URDF's mesh: inside an asset
    directory (default :func:`directories`) or a package's share directory."""
    dirs = tuple(dirs) if dirs is not None else tuple(directories())
    return _inside(real, dirs) or _inside(real, _package_shares())


def _locate(path: str, dirs: tuple[str, ...]) -> str | None:
    """The resolved file ``path`` names (it may not exist); None if it is outside."""
    if os.path.isabs(path):
        real = os.path.realpath(path)
        return real if _inside(real, dirs) else None
    candidates = [os.path.realpath(os.path.join(d, path)) for d in dirs]
    for real in candidates:
        if os.path.exists(real):
            return real if _inside(real, dirs) else None
    inside = [real for real in candidates if _inside(real, dirs)]
    return inside[0] if inside else None


# --- content --------------------------------------------------------------------------

def problem(path: str, dirs: Iterable[str] | None = None) -> str | None:
    """What is wrong with the content of the model file at ``path`` (resolved), None if
    nothing. A mesh is read once per (path, modification time, size); a URDF is parsed
    each time (the meshes it names may change on their own)."""
    dirs = tuple(dirs) if dirs is not None else tuple(directories())
    name = os.path.basename(path)
    try:
        fmt = FORMATS.get(os.path.splitext(path)[1].lower())
        if fmt in ('urdf', 'sdf'):
            _model_meshes(path, dirs)
        elif fmt in ('obj', 'stl'):
            _mesh_problem(path, dirs)
        else:
            raise _Malformed(_FORMATS_MESSAGE)
    except _Malformed as exc:
        return f'{name}: {exc}'
    except OSError as exc:
        return f'{name}: cannot be read ({exc.strerror or exc})'
    return None


def _mesh_problem(path: str, dirs: tuple[str, ...]) -> None:
    stat = os.stat(path)
    message = _mesh_problem_cached(path, stat.st_mtime_ns, stat.st_size, dirs)
    if message is not None:
        raise _Malformed(message)


@functools.lru_cache(maxsize=1024)
def _mesh_problem_cached(path: str, mtime: int, size: int,
                         dirs: tuple[str, ...]) -> str | None:
    try:
        _read(path, FORMATS[os.path.splitext(path)[1].lower()], dirs)
    except _Malformed as exc:
        return str(exc)
    return None


def read_mesh(path: str) -> Mesh:
    """The triangles of the OBJ or STL file at ``path``.

    Raises:
        ProjectionError: kind ``invalid_scenario`` if it is not a well formed mesh.
    """
    stat = os.stat(path)
    try:
        return _read_cached(path, stat.st_mtime_ns, stat.st_size)
    except _Malformed as exc:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'model file {path}: {exc}') from None


@functools.lru_cache(maxsize=16)
def _read_cached(path: str, mtime: int, size: int) -> Mesh:
    fmt = FORMATS.get(os.path.splitext(path)[1].lower())
    if fmt not in ('obj', 'stl'):
        raise _Malformed('a mesh is an .obj or .stl file')
    return _read(path, fmt, None)


def _read(path: str, fmt: str, dirs: tuple[str, ...] | None) -> Mesh:
    data = Path(path).read_bytes()
    return _read_obj(path, data, dirs) if fmt == 'obj' else _read_stl(data)


def _read_obj(path: str, data: bytes, dirs: tuple[str, ...] | None) -> Mesh:
    vertices: list[tuple[float, float, float]] = []
    triangles: list[tuple[int, int, int]] = []
    faces: list[tuple[int, list[int]]] = []   # (line, vertex indices as written)
    for number, line in enumerate(data.decode('utf-8', errors='replace').splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        if parts[0] == 'v':
            try:
                x, y, z = (float(v) for v in parts[1:4])
            except ValueError:
                raise _Malformed(f'line {number}: a vertex needs three numbers') from None
            vertices.append((x, y, z))
        elif parts[0] == 'f':
            try:
                indices = [int(p.split('/')[0]) for p in parts[1:]]
            except ValueError:
                raise _Malformed(f'line {number}: a face is a list of vertex indices') from None
            if len(indices) < 3:
                raise _Malformed(f'line {number}: a face needs three vertices')
            # Negative indices count back from the vertices read so far.
            faces.append((number, [i - 1 if i > 0 else len(vertices) + i for i in indices]))
        elif parts[0] == 'mtllib' and dirs is not None:
            for library in parts[1:]:
                real = os.path.realpath(os.path.join(os.path.dirname(path), library))
                if not _inside(real, dirs):
                    raise _Malformed(f'its material library {library!r} is outside the '
                                     'asset directories')
    if not vertices:
        raise _Malformed('no vertices (lines "v x y z")')
    if not faces:
        raise _Malformed('no faces (lines "f i j k")')
    for number, indices in faces:
        if not all(0 <= i < len(vertices) for i in indices):
            raise _Malformed(f'line {number}: a face names a vertex that does not exist '
                             f'({len(vertices)} vertices)')
        triangles += [(indices[0], indices[k], indices[k + 1])
                      for k in range(1, len(indices) - 1)]
    return Mesh(vertices, triangles)


def _read_stl(data: bytes) -> Mesh:
    if len(data) >= 84:
        (count,) = struct.unpack_from('<I', data, 80)
        if count > 0 and len(data) == 84 + 50 * count:
            vertices: list[tuple[float, float, float]] = []
            for record in struct.iter_unpack('<12fH', data[84:]):
                vertices += [tuple(record[3:6]), tuple(record[6:9]), tuple(record[9:12])]
            return _triangles(vertices)
    text = data.decode('ascii', errors='replace')
    if not text.lstrip().startswith('solid') or 'facet' not in text:
        raise _Malformed('neither a binary STL (84 + 50 n bytes for the n triangles its '
                         'header counts) nor an ASCII one ("solid", "facet", "vertex")')
    vertices = []
    for number, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if parts and parts[0] == 'vertex':
            try:
                x, y, z = (float(v) for v in parts[1:4])
            except ValueError:
                raise _Malformed(f'line {number}: a vertex needs three numbers') from None
            vertices.append((x, y, z))
    if not vertices or len(vertices) % 3:
        raise _Malformed('an ASCII STL needs facets of three vertices each')
    return _triangles(vertices)


def _triangles(vertices: list[tuple[float, float, float]]) -> Mesh:
    return Mesh(vertices, [(i, i + 1, i + 2) for i in range(0, len(vertices), 3)])


def _model_meshes(path: str, dirs: tuple[str, ...]) -> list[str]:
    """The resolved mesh files the URDF or SDF at ``path`` names (checking them)."""
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as exc:
        raise _Malformed(f'not well formed XML ({exc})') from None
    sdf = os.path.splitext(path)[1].lower() == '.sdf'
    if root.tag != ('sdf' if sdf else 'robot'):
        raise _Malformed(f'the root element is <{root.tag}>, not <{"sdf" if sdf else "robot"}>')
    if sdf and not any(model.find('link') is not None for model in root.iter('model')):
        raise _Malformed('the <sdf> has no <model> with a <link>')
    if not sdf and root.find('link') is None:
        raise _Malformed('the <robot> has no <link>')
    meshes = []
    for mesh in root.iter('mesh'):
        uri = mesh.find('uri')
        name = (uri.text or '').strip() if sdf and uri is not None else mesh.get('filename')
        if not name:
            raise _Malformed(f'a <mesh> without {"a <uri>" if sdf else "a filename"}')
        if sdf:   # PyBullet joins it to the SDF's directory, a leading / or not
            name = name.removeprefix('model://').lstrip('/')
        real = _urdf_mesh(path, name, dirs)
        if real is None:
            raise _Malformed(f'its mesh {name!r} is outside the asset directories')
        if not os.path.isfile(real):
            raise _Malformed(f'its mesh {name!r} does not exist')
        if FORMATS.get(os.path.splitext(real)[1].lower()) in ('obj', 'stl'):
            try:
                _mesh_problem(real, dirs)
            except _Malformed as exc:
                raise _Malformed(f'its mesh {name!r}: {exc}') from None
        meshes.append(real)
    return meshes


def _urdf_mesh(urdf: str, name: str, dirs: tuple[str, ...]) -> str | None:
    """Where PyBullet finds a URDF's mesh: relative to the URDF (``package://`` stripped,
    also from the URDF's parent directories); None if that is outside ``dirs``."""
    for prefix in ('package://', 'file://'):
        if name.startswith(prefix):
            name = name[len(prefix):]
    if os.path.isabs(name):
        candidates = [name]
    else:
        base = os.path.dirname(urdf)
        candidates = [os.path.join(base, *(['..'] * up), name) for up in range(4)]
    reals = [os.path.realpath(c) for c in candidates]
    for real in reals:
        if os.path.exists(real):
            return real if inside_model_roots(real, dirs) else None
    return reals[0] if inside_model_roots(reals[0], dirs) else None


# --- content digests --------------------------------------------------------------------

def digest(path: str, dirs: Iterable[str] | None = None) -> str:
    """SHA-256 of the model file at ``path`` (resolved, well formed) and, for a URDF, of
    the meshes it names (resolved in ``dirs``, default :func:`directories`); each file is
    read once per (path, modification time, size)."""
    stat = os.stat(path)
    own = _file_digest(path, stat.st_mtime_ns, stat.st_size)
    if FORMATS.get(os.path.splitext(path)[1].lower()) not in ('urdf', 'sdf'):
        return own
    dirs = tuple(dirs) if dirs is not None else tuple(directories())
    try:
        meshes = _model_meshes(path, dirs)
    except _Malformed as exc:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'model file {path}: {exc}') from None
    total = hashlib.sha256(own.encode())
    for mesh in sorted(set(meshes)):
        stat = os.stat(mesh)
        total.update(f'{mesh}:{_file_digest(mesh, stat.st_mtime_ns, stat.st_size)}'.encode())
    return total.hexdigest()


@functools.lru_cache(maxsize=1024)
def _file_digest(path: str, mtime: int, size: int) -> str:
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for block in iter(lambda: f.read(1 << 20), b''):
            digest.update(block)
    return digest.hexdigest()
