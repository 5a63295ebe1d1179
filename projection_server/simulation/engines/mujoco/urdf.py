"""URDF models on MuJoCo: a URDF arm (the ``urdf`` robot model) and ``rigid_object``s of
shape ``mesh`` and ``urdf``.

A URDF is compiled by MuJoCo's own URDF compiler (``MjSpec.from_string``) into a spec of its
own, then attached into the world's spec under the entity's name. Before that, the URDF's
visual elements are dropped and each collision mesh's file is resolved as PyBullet finds it
(relative to the URDF, ``package://`` stripped) and must lie inside the asset directories
(:mod:`projection_server.assets`); the ``<mujoco><compiler>`` extension keeps every link a
body of its own (``fusestatic`` off: its frame is on ``/tf`` as on PyBullet) and the paths
as resolved (``strippath`` off). A mesh file of several objects (an OBJ's ``o``/``g``
groups, as V-HACD writes them) becomes one mesh per object, each colliding as its convex
hull, as PyBullet's compound of hulls does; MuJoCo collides every mesh as its convex hull.

**An arm** (:func:`urdf_robot`) has the facts of :mod:`~projection_server.simulation.robots.
urdf_arm`, read and checked there (:func:`~projection_server.simulation.robots.urdf_arm.
arm_facts`, and a linkage's :func:`~projection_server.simulation.robots.urdf_arm.
linkage_facts`); its joints' indices and limits are read from the
kinematic copy that solves its poses (:mod:`~projection_server.simulation.robots.
kinematics`, the same solver and solutions on both engines). Every arm joint, and the
fingers, is moved as PyBullet's position and velocity motors move them: a *drive* beside the
joint (:func:`~.builders.add_drive`) is set its speed every step, and pulls the joint
through a tendon whose friction loss is the joint's force limit (its URDF effort; a
finger's at most the commanded grip force, at most the robot's ``max_force``). An arm
joint's drive runs at ``TRACKING_RATE`` times the joint's error (PyBullet's position gain
of the same rate). Revolute fingers (a linkage) are commanded as
:class:`~projection_server.simulation.robots.linkage.LinkageGripper` commands them, from
the same opening table (:class:`MujocoLinkageGripper`). Mimic joints are MuJoCo's joint
equalities, as its URDF compiler makes them, as stiff as the drives (with MuJoCo's default
softness a linkage's fingers turn out of parallel under a 5 N grip). The arm does not
collide with itself (no pairs of one entity's geoms); its base link, fixed, collides with
what moves only. An SDF robot is not built: an error naming the robot and the engine.

**A mesh** (:func:`rigid_mesh`) collides as the parts of its convex decomposition (the
V-HACD decomposition PyBullet's moving mesh uses, :func:`~projection_server.simulation.
objects.rigid_object.convex_decomposition`), static or moving (MuJoCo has no concave
triangle meshes); its centre of mass the centroid of its volume, its inertia that of its
bounding box (Bullet's of a compound). **A URDF object** (:func:`rigid_urdf`) is its URDF
compiled, free unless static; a ``mass`` is shared among its links in the URDF's
proportions, and each link's inertia is its collision shapes' (of uniform density), scaled
to its mass, as PyBullet computes it. Its joints are passive.
"""

from __future__ import annotations

import functools
import math
import os
from pathlib import Path
from typing import Any, Sequence, TYPE_CHECKING
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from projection_server import assets
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.engines.mujoco.builders import (_euler_quat, _register,
                                                                  _release, _subtree,
                                                                  add_drive, DRIVE_SOLIMP,
                                                                  DRIVE_SOLREF)
from projection_server.simulation.physics import Body, GripperBase, Shape
from projection_server.simulation.robots.linkage import LEVER_STEP, OpeningTable
from projection_server.simulation.robots.manipulator import ArmBase
from projection_server.simulation.robots.urdf_arm import joint_infos

if TYPE_CHECKING:
    from projection_server.simulation.engines.mujoco.physics import MujocoPhysics
    from projection_server.simulation.robots.urdf_arm import ArmFacts, JointInfo, LinkageFacts
    from projection_server.simulation.engines.mujoco.world import WorldSpec
    from projection_server.simulation.scenario import Entity

__all__ = ['MujocoArm', 'MujocoLinkageGripper', 'load_urdf', 'obj_parts', 'rigid_mesh',
           'rigid_urdf', 'urdf_robot']


def _cannot(entity: str, what: str) -> ProjectionError:
    return ProjectionError(ErrorKind.INVALID_SETTINGS,
                           f'the mujoco engine cannot build {entity}: {what}')


# --- URDF and mesh files ------------------------------------------------------------------------
def load_urdf(path: str, entity: str, scale: float = 1.0) -> Any:
    """The ``MjSpec`` of the URDF at ``path`` (see the module doc), its lengths times
    ``scale`` (PyBullet's ``globalScaling``: its masses as given)."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity}: cannot read {path}: {exc}') from None
    for link in root.iter('link'):
        for visual in link.findall('visual'):
            link.remove(visual)
    dirs = tuple(assets.directories())
    for mesh in root.iter('mesh'):
        name = mesh.get('filename', '')
        real = assets._urdf_mesh(path, name, dirs)   # where PyBullet finds it, if inside
        if real is None or not os.path.isfile(real):
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'{entity}: the mesh {name!r} of {Path(path).name} is not '
                                  'a file inside the asset directories')
        mesh.set('filename', real)
    if scale != 1.0:
        _scale(root, scale)
    for old in root.findall('mujoco'):
        root.remove(old)
    # balanceinertia: a URDF's inertia that no body has (A + B < C) made one that a body
    # has (PyBullet takes its links' inertia from their collision shapes)
    ET.SubElement(ET.SubElement(root, 'mujoco'), 'compiler', discardvisual='true',
                  fusestatic='false', strippath='false', balanceinertia='true',
                  meshdir=str(Path(path).parent))
    try:
        spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding='unicode'))
    except ValueError as exc:   # MuJoCo's parser's error
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity}: MuJoCo cannot compile {path}: {exc}') from None
    _split_meshes(spec)
    return spec


def _scale(root: Any, scale: float) -> None:
    """The URDF's lengths times ``scale``: origins, shapes, prismatic limits."""
    def times(element: Any, key: str, default: str | None = None) -> None:
        value = element.get(key, default)
        if value is not None:
            element.set(key, ' '.join(repr(float(v) * scale) for v in value.split()))
    for origin in root.iter('origin'):
        times(origin, 'xyz')
    for box in root.iter('box'):
        times(box, 'size')
    for shape in (*root.iter('cylinder'), *root.iter('sphere'), *root.iter('capsule')):
        times(shape, 'radius')
        times(shape, 'length')
    for mesh in root.iter('mesh'):
        times(mesh, 'scale', '1 1 1')
    for joint in root.iter('joint'):
        limit = joint.find('limit')
        if joint.get('type') == 'prismatic' and limit is not None:
            times(limit, 'lower')
            times(limit, 'upper')


def obj_parts(path: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """The objects of the OBJ file at ``path`` (its ``o``/``g`` groups; the whole file if it
    has none): each as vertices (n, 3) and triangles (m, 3) of its own vertices."""
    vertices: list[list[float]] = []
    groups: list[list[list[int]]] = [[]]
    with open(path, encoding='utf-8', errors='replace') as f:
        for line in f:
            if line.startswith('v '):
                vertices.append([float(v) for v in line.split()[1:4]])
            elif line.startswith(('o ', 'g ')):
                if groups[-1]:
                    groups.append([])
            elif line.startswith('f '):
                ids = []
                for item in line.split()[1:]:
                    i = int(item.split('/')[0])
                    ids.append(i - 1 if i > 0 else len(vertices) + i)
                groups[-1] += [[ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1)]
    table = np.asarray(vertices, float)
    parts = []
    for faces in groups:
        if not faces:
            continue
        faces_array = np.asarray(faces, int)
        used, inverse = np.unique(faces_array, return_inverse=True)
        parts.append((table[used], inverse.reshape(-1, 3)))
    return parts


def _split_meshes(spec: Any) -> None:
    """Each mesh geom whose OBJ has several objects becomes one geom per object."""
    for mesh in list(spec.meshes):
        if not mesh.file.lower().endswith('.obj'):
            continue
        parts = obj_parts(mesh.file)
        if len(parts) < 2:
            continue
        users = [g for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH
                 and g.meshname == mesh.name]
        for i, (vertices, faces) in enumerate(parts):
            part = spec.add_mesh(name=f'{mesh.name}/{i}', scale=list(mesh.scale),
                                 uservert=vertices.ravel().tolist(),
                                 userface=faces.ravel().tolist())
            for geom in users:
                geom.parent.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=part.name,
                                     pos=list(geom.pos), quat=list(geom.quat))
        for geom in users:
            spec.delete(geom)
        spec.delete(mesh)


def _attach(world: WorldSpec, child: Any, entity: Entity) -> Any:
    """The URDF spec's root body attached into the world at the entity's pose (its base
    link's frame), named as the entity; its other bodies and joints prefixed
    ``entity/``."""
    frame = world.spec.worldbody.add_frame(pos=list(entity.pose.xyz),
                                           quat=_euler_quat(entity.pose.rpy))
    base = frame.attach_body(child.worldbody.first_body(), f'{entity.name}/', '')
    base.name = entity.name
    return base


# --- the arm ----------------------------------------------------------------------------------
@functools.cache
def _bullet_joints(path: str) -> tuple[JointInfo, ...]:
    """The URDF's joints in PyBullet's order, read once per process from a copy loaded in
    the kinematic solvers' client (the arm's joint indices are the solver's)."""
    from projection_server.simulation.robots.kinematics import _client, load_robot

    client = _client()
    try:
        body = load_robot(client, path, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    except Exception:   # pybullet.error: PyBullet cannot load it either
        body = -1
    if body < 0:
        raise ValueError(f'cannot load {path}')
    try:
        return joint_infos(client, body)
    finally:
        client.removeBody(body)


def urdf_robot(world: WorldSpec, entity: Entity, gripper: Entity | None = None) -> None:
    """The ``urdf`` robot model on MuJoCo (see the module doc)."""
    import pybullet

    from projection_server.simulation.robots.urdf_arm import (arm_facts, given_fingers,
                                                              HOLD_FORCE, FRICTION,
                                                              TRACKING_RATE)

    p = entity.properties
    if not world.tool_control:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: a URDF arm is driven by plans only (the named '
                              'programs drive the PR2 gripper); give a plan([...])')
    path, file = p['file'], Path(p['file']).name
    if path.lower().endswith('.sdf'):
        raise _cannot(entity.name, f'an SDF robot ({file}; MuJoCo compiles URDF robots)')
    try:
        infos = _bullet_joints(path)
    except ValueError:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: cannot load {path}') from None
    facts = arm_facts(entity, infos)
    joints, fingers, arm, held = facts.joints, facts.fingers, facts.arm, facts.held
    mimic, tool = facts.mimic, facts.tool
    start = dict(facts.start)
    linkage = None
    if facts.revolute:   # the fingers start open
        linkage = _linkage(entity, facts)
        start = {j: v for j, v in linkage.start.items() if j not in held}

    child = load_urdf(path, entity.name)
    for coupling in child.equalities:   # mimic joints: geared, as stiff as the drives
        coupling.solref, coupling.solimp = list(DRIVE_SOLREF), list(DRIVE_SOLIMP)
    base = _attach(world, child, entity)
    prefix = f'{entity.name}/'
    for geom in base.geoms:   # the base is fixed: it collides with what moves only
        world.adopt(geom, entity.name, 'static', FRICTION)
    links = []
    for body in _subtree(base):
        links.append(body.name[len(prefix):])
        for geom in body.geoms:
            world.adopt(geom, entity.name, 'robot', FRICTION)
    servos = [*arm, *held]
    forces = {j: infos[j].effort for j in arm} | {j: HOLD_FORCE for j in held}
    for j in [*servos, *fingers]:
        add_drive(world, prefix + infos[j].name,
                  forces.get(j, max(infos[j].effort, 0.0) or HOLD_FORCE))
    targets = dict(zip(arm, facts.home)) | held
    orientation = tuple(world_quaternion(entity.pose.rpy))

    def after(physics: MujocoPhysics) -> None:
        from projection_server.simulation.engines.mujoco.physics import MujocoGripper

        model, data = physics.model, physics.data
        root = model.body(entity.name).id
        link_ids = {model.body(prefix + name).id: name for name in links}
        joint = {j: model.joint(prefix + infos[j].name).id
                 for j in range(len(infos)) if infos[j].kind != pybullet.JOINT_FIXED}
        drive = {j: model.joint(prefix + infos[j].name + '/drive').id
                 for j in [*servos, *fingers]}

        def put(j: int, value: float) -> None:
            data.qpos[model.jnt_qposadr[joint[j]]] = value
            if j in drive:
                data.qpos[model.jnt_qposadr[drive[j]]] = value
        for j, value in [*targets.items(), *start.items()]:
            put(j, value)
        for name, (parent, multiplier, offset) in mimic.items():
            if name in joints and parent in joints and joints[name] not in start:
                put(joints[name], multiplier * float(
                    data.qpos[model.jnt_qposadr[joint[joints[parent]]]]) + offset)
        physics.add_body(Body(entity.name, entity.cls, root, False, None,
                              links=dict(sorted(link_ids.items())), driven=True, urdf=path))
        finger_joints = {'fingers': [joint[j] for j in fingers],
                         'drives': [drive[j] for j in fingers],
                         'tendons': [model.tendon(prefix + infos[j].name + '/drive').id
                                     for j in fingers]}
        if linkage is not None:
            carried = [model.body(prefix + infos[j].link).id for j in linkage.carried]
            hand = MujocoLinkageGripper(
                physics, entity.name, root, finger_joints, linkage.open, linkage.closed,
                linkage.table, [max(infos[j].effort, 0.0) or HOLD_FORCE for j in fingers],
                p['max_force'], TRACKING_RATE, [infos[j].link for j in linkage.pads],
                carried)
            hand.open(hand.max_opening, speed=0.1)
        else:
            pads = p.get('pad_links') or [infos[j].link for j in fingers]
            hand = MujocoGripper(
                physics, entity.name, root, finger_joints, {}, [],
                max_joint_force=max(infos[j].effort for j in fingers),
                max_force=p['max_force'], max_opening=sum(infos[j].upper for j in fingers),
                tracking_rate=TRACKING_RATE, finger_links=pads)
            hand.open(sum(start.values()) if given_fingers(facts) else hand.max_opening,
                      speed=0.1)
        physics.grippers[entity.name] = hand
        tool_orientation = world_quaternion(p.get('tool_rpy', (0.0, 0.0, 0.0)))
        qpos = {j: int(model.jnt_qposadr[i]) for j, i in joint.items()}
        manipulator = MujocoArm(physics, entity.name, root, path,
                                (entity.pose.xyz, orientation), arm, tool, p['tool_offset'],
                                hand, tool_orientation, qpos,
                                [(j, int(model.jnt_dofadr[drive[j]])) for j in servos],
                                targets, TRACKING_RATE)
        manipulator.servo(*manipulator.tool_pose())
        physics.manipulators[entity.name] = manipulator
    world.after.append(after)


def _linkage(entity: Entity, facts: ArmFacts) -> LinkageFacts:
    """Revolute fingers' facts as the PyBullet model finds them
    (:func:`~projection_server.simulation.robots.urdf_arm.linkage_facts`, on a copy of the
    robot at its pose in the kinematic solvers' client: the same table as PyBullet's, of
    the same key)."""
    from projection_server.simulation.robots.kinematics import _client, load_robot
    from projection_server.simulation.robots.urdf_arm import linkage_facts

    c = _client()
    body = load_robot(c, entity.properties['file'], entity.pose.xyz,
                      world_quaternion(entity.pose.rpy))
    try:
        return linkage_facts(c, body, entity, facts)
    finally:
        c.removeBody(body)


class MujocoLinkageGripper(GripperBase):
    """:class:`~projection_server.simulation.robots.linkage.LinkageGripper` on MuJoCo: the
    same table, levers and commands, each finger joint moved through its drive (the
    tendon's friction loss its torque limit: closing, the force asked for times the
    joint's lever, set anew as the fingers move; opening, its effort); closing and holding,
    the fingers' links' weight carried by an upward force at their centres of mass."""

    def __init__(self, physics: MujocoPhysics, name: str, body_id: int,
                 joints: dict[str, list[int]], open_values: Sequence[float],
                 closed_values: Sequence[float], table: tuple[Sequence[float], Sequence[float]],
                 torques: Sequence[float], max_force: float, rate: float,
                 finger_links: Sequence[str], carried: Sequence[int]):
        self._table = OpeningTable(open_values, closed_values, table)
        super().__init__(name, body_id, joints, [], max_force, self._table.max_opening,
                         finger_links)
        self._physics = physics
        model = physics.model
        self._qpos = np.array([model.jnt_qposadr[j] for j in joints['fingers']])
        self._drive_dof = np.array([model.jnt_dofadr[j] for j in joints['drives']])
        self._tendons = np.array(joints['tendons'])
        self._torques = np.asarray(torques, float)
        self._rate = rate
        self._speed = 0.0
        self._target = self._table.open.copy()
        self._limit = np.full(len(self._fingers), math.inf)
        self._set_at = 1.0
        self._carried = np.asarray(carried, int)
        g = -float(model.opt.gravity[2])
        self._weights = np.array([[0.0, 0.0, float(model.body_mass[b]) * g] for b in carried])
        physics.controllers.append(self._control)

    def position(self) -> float:
        table = self._table
        q = self._physics.data.qpos[self._qpos]
        return float(np.mean((q - table.closed) / table.span))

    def levers(self, u: float) -> np.ndarray:
        return self._table.levers(u)

    def _control(self) -> None:
        data = self._physics.data
        if self.command == 'close':
            u = self.position()
            if abs(u - self._set_at) >= LEVER_STEP:
                self._set_closing(u)
            speed = np.full(len(self._fingers), -self._table.rate(self._speed)) * self._table.span
        else:
            error = self._target - data.qpos[self._qpos]
            speed = np.clip(self._rate * error, -self._limit, self._limit)
        data.qvel[self._drive_dof] = speed

    def _set_closing(self, u: float) -> None:
        self._physics.model.tendon_frictionloss[self._tendons] = (self.commanded_force
                                                                  * self.levers(u))
        self._set_at = u

    def close(self, force: float, speed: float) -> None:
        force = min(force, self.max_force)
        self.command, self.commanded_force = 'close', force
        self._speed = speed
        self._set_closing(self.position())
        if len(self._carried):
            self._physics.data.xfrc_applied[self._carried, :3] = self._weights

    def open(self, opening: float, speed: float) -> None:
        self.command, self.commanded_force = 'open', 0.0
        table = self._table
        self._target = table.closed + table.position_at(opening) * table.span
        self._limit = table.rate(speed) * np.abs(table.span)
        self._physics.model.tendon_frictionloss[self._tendons] = self._torques
        if len(self._carried):
            self._physics.data.xfrc_applied[self._carried, :3] = 0.0

    def state(self) -> tuple[float, float]:
        """``(opening, measured force)``: the opening at the fingers' position; the mean
        pad force of the drives' tendons' friction through their levers."""
        data = self._physics.data
        u = self.position()
        first, last = data.ne, data.ne + data.nf
        ids, forces = data.efc_id[first:last].tolist(), data.efc_force[first:last].tolist()
        kinds = data.efc_type[first:last].tolist()
        tendon = mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON
        torque = {i: abs(f) for i, f, k in zip(ids, forces, kinds) if k == tendon}
        torques = np.array([torque.get(int(t), 0.0) for t in self._tendons])
        return self._table.opening_at(u), float(np.mean(torques / self.levers(u)))

    def pad_faces(self) -> list[Any]:
        return []


def world_quaternion(rpy: Sequence[float]) -> tuple[float, float, float, float]:
    from projection_server.simulation.engines.mujoco.physics import MujocoPhysics

    return MujocoPhysics.quaternion_from_euler(rpy)


class MujocoArm(ArmBase):
    """An arm (:class:`~projection_server.simulation.robots.manipulator.ArmBase`) on MuJoCo:
    the same solver on the same kinematic copy as PyBullet's; the joints are read from
    MuJoCo's ``qpos`` and servoed through their drives (``servos``: PyBullet index, the
    drive's dof), at ``rate`` times their error a second, each step; ``targets`` their
    first targets."""

    def __init__(self, physics: MujocoPhysics, name: str, body_id: int, urdf: str,
                 base: tuple[Sequence[float], Sequence[float]], joints: Sequence[int],
                 tool_link: int, tool_offset: Sequence[float], gripper: Any,
                 tool_orientation: Sequence[float], qpos: dict[int, int],
                 servos: list[tuple[int, int]], targets: dict[int, float], rate: float):
        super().__init__(name, body_id, gripper, urdf, 1.0, base, joints, tool_link,
                         tool_offset, tool_orientation)
        self._physics = physics
        self._movable_qpos = np.array([qpos[j] for j in self._joints])
        self._servo_qpos = np.array([qpos[j] for j, _ in servos])
        self._servo_dof = np.array([dof for _, dof in servos])
        self._slot = {j: i for i, (j, _) in enumerate(servos)}
        self._targets = np.array([targets[j] for j, _ in servos], float)
        self._rate = rate
        self._home = np.asarray(self._now())
        physics.controllers.append(self._control)

    def _now(self) -> list[float]:
        return self._physics.data.qpos[self._movable_qpos].tolist()

    def _control(self) -> None:
        data = self._physics.data
        data.qvel[self._servo_dof] = self._rate * (self._targets
                                                   - data.qpos[self._servo_qpos])

    def _command(self, values: list[float]) -> None:
        for j, value in zip(self._arm, values):
            self._targets[self._slot[j]] = value


# --- rigid objects ----------------------------------------------------------------------------
def _box_inertia(mass: float, size: np.ndarray) -> list[float]:
    x, y, z = (float(v) ** 2 for v in size)
    return [mass * (y + z) / 12, mass * (x + z) / 12, mass * (x + y) / 12]


def rigid_mesh(world: WorldSpec, entity: Entity) -> None:
    """A ``rigid_object`` of shape ``mesh`` (see the module doc)."""
    from projection_server.simulation.objects.rigid_object import (_centroid, COLOR,
                                                                   convex_decomposition)

    p = entity.properties
    path, scale, mass = p['file'], float(p.get('scale', 1.0)), float(p['mass'])
    static = mass == 0.0
    mesh = assets.read_mesh(path)
    vertices = np.asarray(mesh.vertices, dtype=float) * scale
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    centre = (_centroid(vertices, np.asarray(mesh.triangles, dtype=int), low, high)
              if not static else np.zeros(3))
    body = world.spec.worldbody.add_body(name=entity.name, pos=list(entity.pose.xyz),
                                         quat=_euler_quat(entity.pose.rpy))
    if not static:
        body.add_freejoint()
        body.mass, body.ipos, body.iquat = mass, centre.tolist(), [1.0, 0.0, 0.0, 0.0]
        body.inertia = _box_inertia(mass, np.maximum(high - low, 1e-4))
        body.explicitinertial = True
    for i, (part, faces) in enumerate(obj_parts(convex_decomposition(path))):
        if len(part) < 4:
            continue   # no volume: no hull
        asset = world.spec.add_mesh(name=f'{entity.name}/{i}', scale=[scale] * 3,
                                    uservert=part.ravel().tolist(),
                                    userface=faces.ravel().tolist())
        world.geom(body, entity.name, 'static' if static else 'dynamic', p['friction'],
                   type=mujoco.mjtGeom.mjGEOM_MESH, meshname=asset.name)
    box = Shape('box', tuple(np.maximum(high - low, 1e-4)), COLOR)
    _register(world, entity, static, None,
              link_shapes={-1: [(box, tuple(((low + high) / 2 - centre).tolist()))]})
    _breakable(world, entity)


def rigid_urdf(world: WorldSpec, entity: Entity) -> None:
    """A ``rigid_object`` of shape ``urdf`` (see the module doc)."""
    from projection_server.simulation.objects.rigid_object import COLOR

    p = entity.properties
    child = load_urdf(p['file'], entity.name, float(p.get('scale', 1.0)))
    bodies = [child.worldbody.first_body(), *_subtree(child.worldbody.first_body())]
    urdf_masses = [float(b.mass) for b in bodies]
    mass = p.get('mass')
    jointed = any(b.joints for b in bodies[1:])
    static = mass == 0.0 or (mass is None and urdf_masses[0] == 0.0 and not jointed)
    if not static:
        masses = list(urdf_masses)
        if mass is not None and mass > 0.0:
            total = sum(urdf_masses)
            masses = ([m * mass / total for m in urdf_masses] if total > 0.0
                      else [float(mass)] + urdf_masses[1:])
        # Each link's inertia that of its collision shapes at its mass (PyBullet's).
        probe = child.copy()
        probe.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE
        probe.compiler.discardvisual = False   # there are none: the URDF's were dropped
        compiled = probe.compile()
        for body, m in zip(bodies, masses):
            i = compiled.body(body.name).id
            shape_mass = float(compiled.body_mass[i])
            if m <= 0.0 or shape_mass <= 0.0:
                if body.joints or body is bodies[0]:
                    raise _cannot(entity.name, f'its link {body.name} moves but has no mass')
                continue
            body.mass = m
            body.inertia = (compiled.body_inertia[i] * m / shape_mass).tolist()
            body.fullinertia = [math.nan] * 6   # the URDF's, replaced
            body.iquat = compiled.body_iquat[i].tolist()
            body.explicitinertial = True
    base = _attach(world, child, entity)
    if not static:
        base.add_freejoint()
    kind = 'static' if static else 'dynamic'
    for body in [base, *_subtree(base)]:
        for geom in body.geoms:
            world.adopt(geom, entity.name, kind, p['friction'])
    prefix = f'{entity.name}/'
    names = [b.name for b in _subtree(base)]   # the spec is gone once compiled

    def after(physics: MujocoPhysics) -> None:
        model = physics.model
        root = model.body(entity.name).id
        ids = {model.body(name).id: name[len(prefix):] for name in names}
        physics.add_body(Body(entity.name, entity.cls, root, static, None,
                              links=dict(sorted(ids.items())),
                              link_shapes=_link_boxes(physics, root, list(ids), COLOR)))
    world.after.append(after)
    _breakable(world, entity)


def _link_boxes(physics: MujocoPhysics, root: int, links: list[int], color: Any
                ) -> dict[int, list[tuple[Shape, tuple[float, float, float]]]]:
    """Each link's geoms' bounding box in its frame as ``/tf`` logs it (a link's URDF
    frame, the root's centre of mass)."""
    model = physics.model
    boxes = {}
    for link, body in [(-1, root), *((b, b) for b in links)]:
        corners = []
        for g in range(model.body_geomadr[body],
                       model.body_geomadr[body] + model.body_geomnum[body]):
            centre, half = model.geom_aabb[g][:3], model.geom_aabb[g][3:]
            rot = np.empty(9)
            mujoco.mju_quat2Mat(rot, model.geom_quat[g])
            signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                              for sz in (-1, 1)])
            corners.append(model.geom_pos[g] + (centre + signs * half) @ rot.reshape(3, 3).T)
        if not corners:
            continue
        points = np.vstack(corners) - (model.body_ipos[body] if link == -1 else 0.0)
        low, high = points.min(axis=0), points.max(axis=0)
        boxes[link] = [(Shape('box', tuple(high - low), color),
                        tuple(((low + high) / 2).tolist()))]
    return boxes


def _breakable(world: WorldSpec, entity: Entity) -> None:
    breaking_force = entity.properties.get('breaking_force')
    if breaking_force is None:
        return
    from projection_server.simulation.object_models import RigidBreakable

    def after(physics: MujocoPhysics) -> None:
        physics.models.append(RigidBreakable(
            entity.name, breaking_force,
            lambda physics, name: _release(physics, physics.body(name).body_id)))
    world.after.append(after)

