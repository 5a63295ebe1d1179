"""MuJoCo's builders of the object classes and robot models, one per unit name.

Each takes the world under construction (:class:`~.world.WorldSpec`) and an entity, adds
its bodies and geoms to the spec, and registers what binds them after compilation: the
:class:`~projection_server.simulation.physics.Body` under the entity's name (with the same
shapes, links and frames as the unit's PyBullet builder gives, so that the bags' topics and
``/tf`` are the same), grippers and object models.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable, TYPE_CHECKING

import mujoco
import numpy as np

from projection_server.simulation.object_models import EggShell
from projection_server.simulation.objects.egg import EGG_COLOR, REMAINS_COLOR, REMAINS_FLATNESS
from projection_server.simulation.objects.table import top
from projection_server.simulation.physics import Body, Shape

if TYPE_CHECKING:
    from projection_server.simulation.engines.mujoco.physics import MujocoPhysics
    from projection_server.simulation.engines.mujoco.world import WorldSpec
    from projection_server.simulation.scenario import Entity

__all__ = ['object_builder', 'robot_builder']

PARK_HEIGHT = 1.0   # as the PyBullet gantry's (robots/gantry.py)
DRIVE_MASS = 0.01   # kg of a finger's drive (a body without geoms)
# kg of a set-speed joint's inertia (armature: its own degree of freedom only, no load on
# its parent): what the contacts' forces do to its speed within a step is negligible, so
# the solver sees it as the moving reference it is (a PyBullet motor's stiff constraint).
DRIVE_ARMATURE = 1.0e3
# A friction constraint slips by its softness: the force it holds a finger stopped short
# of its drive with is 2 v / (timeconst (1 - d) A), v the drive's speed, A the finger's
# inverse inertia (50/kg). With d = 0.9999 a finger closing at 0.03 m/s is held with up
# to 600 N, past any grip force, so the friction loss (the grip force), not the softness,
# decides how hard it pushes.
DRIVE_SOLREF = (0.02, 1.0)
# A plan's free gripper is welded to its moving target this hard: it sags 0.15 mm under
# its own weight (a weld's softness, as a contact's, is relative to what it holds).
HOLD_SOLIMP = (0.99, 0.99, 0.001, 0.5, 2.0)
DRIVE_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)


def _quat(physics_quat: Any) -> list[float]:
    x, y, z, w = physics_quat
    return [w, x, y, z]


def _euler_quat(rpy: Any) -> list[float]:
    from projection_server.simulation.engines.mujoco.physics import MujocoPhysics

    return _quat(MujocoPhysics.quaternion_from_euler(rpy))


def _register(world: WorldSpec, entity: Entity, static: bool, shape: Shape | None,
              **extra: Any) -> None:
    def after(physics: MujocoPhysics) -> None:
        body_id = physics.model.body(entity.name).id
        physics.add_body(Body(entity.name, entity.cls, body_id, static, shape, **extra))
    world.after.append(after)


# --- environment, floor, table ---------------------------------------------------------------
def environment(world: WorldSpec, entity: Entity) -> None:
    gravity = entity.properties.get('gravity')
    if gravity is not None:
        world.gravity = float(gravity)


def floor(world: WorldSpec, entity: Entity) -> None:
    body = world.spec.worldbody.add_body(name=entity.name, pos=[0.0, 0.0, entity.pose.xyz[2]])
    world.geom(body, entity.name, 'static', entity.properties['friction'], tuned=True,
               type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 1.0])
    _register(world, entity, True, Shape('box', (20.0, 20.0, 0.001), (0.5, 0.5, 0.5, 1.0)))


def table(world: WorldSpec, entity: Entity) -> None:
    p = entity.properties
    size = (p['size_x'], p['size_y'], p['size_z'])
    position = [entity.pose.xyz[0], entity.pose.xyz[1], top(entity) - size[2] / 2]
    body = world.spec.worldbody.add_body(name=entity.name, pos=position,
                                         quat=_euler_quat((0.0, 0.0, entity.pose.rpy[2])))
    world.geom(body, entity.name, 'static', p['friction'], tuned=True,
               type=mujoco.mjtGeom.mjGEOM_BOX, size=[s / 2 for s in size])
    _register(world, entity, True, Shape('box', size, (0.6, 0.4, 0.2, 1.0)))


# --- egg -------------------------------------------------------------------------------------
def _ellipsoid_inertia(mass: float, a: float, b: float, c: float) -> list[float]:
    return [mass * (b * b + c * c) / 5, mass * (a * a + c * c) / 5, mass * (a * a + b * b) / 5]


def egg(world: WorldSpec, entity: Entity) -> None:
    """A native ellipsoid (no hull), with the :class:`EggShell` model of the PyBullet egg;
    broken, the same body becomes its flat remains in place (a compiled model keeps its
    bodies), released from every robot."""
    p = entity.properties
    semi = (p['length'] / 2, p['diameter'] / 2, p['diameter'] / 2)
    body = world.spec.worldbody.add_body(name=entity.name, pos=list(entity.pose.xyz),
                                         quat=_euler_quat(entity.pose.rpy), mass=p['mass'],
                                         inertia=_ellipsoid_inertia(p['mass'], *semi),
                                         ipos=[0.0, 0.0, 0.0], iquat=[1.0, 0.0, 0.0, 0.0],
                                         explicitinertial=True)
    body.add_freejoint()
    world.geom(body, entity.name, 'dynamic', p['friction'], tuned=True,
               type=mujoco.mjtGeom.mjGEOM_ELLIPSOID, size=list(semi))
    _register(world, entity, False, Shape('sphere', tuple(2 * s for s in semi), EGG_COLOR))

    def tune(model: Any, scenario: Any) -> bool:
        """The mass and inertia of this world's egg (its model may be another's)."""
        mass = _own(scenario, entity.name).properties['mass']
        body = model.body(entity.name).id
        if model.body_mass[body] == mass:
            return False
        model.body_mass[body] = mass
        model.body_inertia[body] = _ellipsoid_inertia(mass, *semi)
        return True
    world.tuners.append(tune)

    def after(physics: MujocoPhysics) -> None:
        own = _own(physics.scenario, entity.name).properties
        physics.models.append(EggShell(entity.name, semi, own.get('breaking_force'),
                                       _remains(semi, own['mass'])))
    world.after.append(after)


def _own(scenario: Any, name: str) -> Entity:
    """The entity ``name`` of ``scenario``: the world's own numbers (of
    :data:`~.world.TUNED`), which the scenario its model was compiled from may not have."""
    return next(e for e in scenario.entities if e.name == name)


def _remains(semi: tuple[float, float, float], mass: float
             ) -> Callable[[MujocoPhysics, str], None]:
    def replace(physics: MujocoPhysics, name: str) -> None:
        model, data = physics.model, physics.data
        body = physics.body(name).body_id
        geom = int(model.body_geomadr[body])
        position, quaternion = physics.base_pose(body)
        touching = bool(physics.contact_points(body))
        linear = physics.base_velocity(body)[0] if not touching else (0.0, 0.0, 0.0)
        rot = physics.rotation_matrix(quaternion)
        bottom = position[2] - math.sqrt(sum((rot[2, i] * semi[i]) ** 2 for i in range(3)))
        yaw = math.atan2(rot[1, 0], rot[0, 0])
        flat = (semi[0], semi[1], semi[2] * REMAINS_FLATNESS)
        model.geom_size[geom] = flat
        model.geom_rbound[geom] = max(flat)
        model.geom_aabb[geom] = [0.0, 0.0, 0.0, *flat]
        model.body_inertia[body] = _ellipsoid_inertia(mass, *flat)
        _release(physics, body)
        joint = int(model.body_jntadr[body])
        address, dof = int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint])
        data.qpos[address:address + 3] = (position[0], position[1], bottom + flat[2])
        data.qpos[address + 3:address + 7] = _euler_quat((0.0, 0.0, yaw))
        data.qvel[dof:dof + 6] = (*linear, 0.0, 0.0, 0.0)
        mujoco.mj_forward(model, data)
        physics.replace_body(name, body, Shape('sphere', tuple(2 * s for s in flat),
                                               REMAINS_COLOR))
    return replace


def _release(physics: MujocoPhysics, body: int) -> None:
    """No robot holds ``body`` any more: the pairs of its geoms with the robots' geoms never
    touch (a pair's margin is how near its geoms make a contact)."""
    model = physics.model
    robots = {b.body_id for b in physics.bodies.values() if b.driven}
    owner = physics._owner
    for pair in range(model.npair):
        a, b = int(owner[model.pair_geom1[pair]][0]), int(owner[model.pair_geom2[pair]][0])
        if (a == body and b in robots) or (b == body and a in robots):
            model.pair_margin[pair] = -1.0e3


# --- rigid objects ------------------------------------------------------------------------------


def rigid_object(world: WorldSpec, entity: Entity) -> None:
    """A box, cylinder or sphere (MuJoCo's own primitives) of the entity's mass, centred on
    its pose, static for mass 0; breakable as on PyBullet
    (:class:`~projection_server.simulation.object_models.RigidBreakable`). Meshes and
    URDF objects are built by :mod:`.urdf`."""
    from projection_server.errors import ErrorKind, ProjectionError
    from projection_server.simulation.object_models import RigidBreakable
    from projection_server.simulation.objects.rigid_object import COLOR

    p = entity.properties
    kind = p['shape']
    if kind in ('mesh', 'urdf'):
        from projection_server.simulation.engines.mujoco.urdf import rigid_mesh, rigid_urdf

        (rigid_mesh if kind == 'mesh' else rigid_urdf)(world, entity)
        return
    if kind == 'box':
        size = (p['size_x'], p['size_y'], p['size_z'])
        geom = {'type': mujoco.mjtGeom.mjGEOM_BOX, 'size': [v / 2 for v in size]}
    elif kind == 'cylinder':
        size = (2 * p['radius'], 2 * p['radius'], p['height'])
        geom = {'type': mujoco.mjtGeom.mjGEOM_CYLINDER, 'size': [p['radius'], p['height'] / 2]}
    elif kind == 'sphere':
        size = (2 * p['radius'],) * 3
        geom = {'type': mujoco.mjtGeom.mjGEOM_SPHERE, 'size': [p['radius']]}
    else:
        raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                              f'the mujoco engine cannot build {entity.name}: a rigid_object '
                              f'of shape {kind} (it builds box, cylinder and sphere)')
    mass = float(p['mass'])
    static = mass == 0.0
    body = world.spec.worldbody.add_body(name=entity.name, pos=list(entity.pose.xyz),
                                         quat=_euler_quat(entity.pose.rpy))
    if not static:
        body.add_freejoint()
    added = world.geom(body, entity.name, 'static' if static else 'dynamic', p['friction'],
                       **geom)
    if not static:
        added.mass = mass   # the primitive's own inertia of that mass, about its centre
    _register(world, entity, static, Shape(kind, size, COLOR))
    breaking_force = p.get('breaking_force')
    if breaking_force is not None:
        def after(physics: MujocoPhysics) -> None:
            physics.models.append(RigidBreakable(
                entity.name, breaking_force,
                lambda physics, name: _release(physics, physics.body(name).body_id)))
        world.after.append(after)


# --- robots ----------------------------------------------------------------------------------
def robot(world: WorldSpec, entity: Entity) -> None:
    name = entity.properties.get('gripper')
    gripper = next((e for e in world.scenario.of_class('gripper') if e.name == name), None)
    build = robot_builder(entity.properties['model'])
    build(world, entity, gripper)


def pr2(world: WorldSpec, entity: Entity, gripper: Entity | None = None) -> None:
    """The PR2 gripper on its gantry, or free for plans (``tool_control``): the URDF of its
    PyBullet model compiled by MuJoCo's URDF importer, its root the gantry's base (a
    mocap body the program places) or free and welded to a mocap body that the plan's tool
    pose moves (:class:`~.physics.MujocoFloatingTool`); the joints set their speeds
    (:class:`~.physics.MujocoGripper`)."""
    from projection_server.simulation.engines.mujoco.physics import MujocoGripper
    from projection_server.simulation.robots.gantry import (_gripper_spec, _pad, _urdf_boxes,
                                                            DEFAULT_GRIPPER, TRACKING_RATE)
    from projection_server.simulation.robots.registry import assets_dir

    asset = (Path(gripper.properties['urdf']).stem if gripper is not None
             else entity.properties.get('gripper', DEFAULT_GRIPPER))
    spec_data = _gripper_spec(asset)
    free = world.tool_control
    urdf = assets_dir() / spec_data['free_urdf' if free else 'urdf']
    child = mujoco.MjSpec.from_file(str(urdf))
    root_link = child.worldbody.first_body().name
    x, y, z = entity.pose.xyz
    prefix = f'{entity.name}/'
    base = world.spec.worldbody.add_frame().attach_body(child.worldbody.first_body(),
                                                        prefix, '')
    base.name, base.pos = entity.name, [x, y, z + PARK_HEIGHT]
    if free:
        # For plans: the palm free, welded to a mocap body (the plan's tool pose moves it).
        base.add_freejoint()
        parked = _parked_orientation()
        base.quat = _quat(parked)
        target = world.spec.worldbody.add_body(name=prefix + 'target', mocap=True,
                                               pos=[x, y, z + PARK_HEIGHT],
                                               quat=_quat(parked))
        world.spec.add_equality(type=mujoco.mjtEq.mjEQ_WELD, name=prefix + 'hold',
                                objtype=mujoco.mjtObj.mjOBJ_BODY, name1=target.name,
                                name2=entity.name, solref=[1.0 / TRACKING_RATE, 1.0],
                                solimp=list(HOLD_SOLIMP),
                                # anchor, the palm's pose in the target's (none), torques
                                data=[0.0] * 6 + [1.0, 0.0, 0.0, 0.0, 1.0] + [0.0])
    else:
        # The URDF's root link is the gantry's base: a mocap body the program places.
        base.mocap = True
    # Without a gripper entity, each link's friction is its URDF's, as Bullet reads it
    # (``<contact><lateral_friction>``; Bullet's default 0.5 where none is given).
    frictions = _urdf_frictions(urdf)
    limits = {'max_force': math.inf, 'max_opening': math.inf}
    if gripper is not None:
        limits = {key: gripper.properties[key] for key in limits}
    joints = spec_data['joints']
    links: list[str] = []
    for geom in base.geoms:   # a free gripper's palm
        world.adopt(geom, entity.name, 'robot', float(gripper.properties['friction'])
                    if gripper is not None else frictions.get(root_link, BULLET_FRICTION))
    for body in _subtree(base):
        link = body.name[len(prefix):]
        links.append(link)
        friction = (float(gripper.properties['friction']) if gripper is not None
                    else frictions.get(link, BULLET_FRICTION))
        for geom in body.geoms:
            world.adopt(geom, entity.name, 'robot', friction)
    for finger in joints['fingers']:
        joint = world.spec.joint(prefix + finger)
        if math.isfinite(limits['max_opening']):
            joint.range = [joint.range[0], min(joint.range[1], limits['max_opening'] / 2)]
    # A PyBullet velocity motor of at most F is a constraint solved with the contacts:
    # each finger is held to a drive (a body beside it on the same axis, of a huge joint
    # inertia, set its speed every step) by a tendon of the two joints with a friction
    # loss of F: the finger moves with its drive until that takes more than F, and then
    # pushes with F.
    for finger in joints['fingers']:
        add_drive(world, prefix + finger, float(spec_data['gantry_force']))
    # The gantry's joints are set their speeds each step too, of the same inertia: a stiff
    # servo would have to be integrated implicitly, and MuJoCo solves the contacts with
    # the plain inertia, so what the pads hold would be pushed ahead of them as they move.
    gantry = [] if free else [joints['lift'], joints['approach']]
    names = [*gantry, *(f + '/drive' for f in joints['fingers'])]
    for joint in gantry:
        world.spec.joint(prefix + joint).armature = DRIVE_ARMATURE
    boxes = _urdf_boxes(urdf)

    def after(physics: MujocoPhysics) -> None:
        model = physics.model
        root = model.body(entity.name).id
        link_ids = {model.body(prefix + link).id: link for link in links}
        index = {link: i for i, link in link_ids.items()}
        index[root_link] = -1
        # The root's frame on /tf is its centre of mass (PyBullet's base frame).
        com = model.body_ipos[root].copy()
        pads = [_pad(index[pad['link']], pad, boxes[pad['collision']],
                     float(spec_data['pad_stiffness']), float(spec_data['pad_rim_radius']))
                for pad in spec_data['pads']]
        link_shapes: dict[int, list[tuple[Shape, tuple[float, float, float]]]] = {}
        for box in boxes.values():
            link = index[box['link']]
            origin = np.asarray(box['origin']) - (com if link < 0 else 0.0)
            link_shapes.setdefault(link, []).append(
                (Shape('box', box['size'], (0.3, 0.3, 0.35, 1.0)), tuple(map(float, origin))))
        physics.add_body(Body(entity.name, entity.cls, root, False, None,
                              links=dict(sorted(link_ids.items())), link_shapes=link_shapes,
                              driven=True, urdf=str(urdf)))
        joint_ids = {n: model.joint(prefix + n).id for n in names}
        actuators: dict[int, int] = {}
        joint_map = {'fingers': [model.joint(prefix + n).id for n in joints['fingers']],
                     'drives': [joint_ids[n + '/drive'] for n in joints['fingers']],
                     'tendons': [model.tendon(prefix + n + '/drive').id
                                 for n in joints['fingers']]}
        if not free:
            joint_map.update(lift=joint_ids[joints['lift']],
                             approach=joint_ids[joints['approach']])
        hand = MujocoGripper(physics, entity.name, root, joint_map, actuators, pads,
                             float(spec_data['gantry_force']), tracking_rate=TRACKING_RATE,
                             mocap=int(model.body_mocapid[root]), **limits)
        physics.grippers[entity.name] = hand
        if free:
            _park(physics, entity, hand, model, prefix, spec_data, limits)
    world.after.append(after)


def add_drive(world: WorldSpec, name: str, force: float) -> None:
    """A drive for the joint ``name``: a body beside the joint's on the same axis (named
    ``name/drive``, as its joint), of a huge joint inertia that a controller sets the speed
    of every step, held to the joint by a tendon ``name/drive`` of the two whose friction
    loss is ``force`` (the most the drive pushes the joint with); the joint's limits as
    stiff as that tendon."""
    joint = world.spec.joint(name)
    # A MuJoCo limit is a soft constraint: a joint pushed into it with F rests
    # (1 - d) timeconst^2 F/m past it (MuJoCo's modelling guide, solver parameters). At the
    # default d = 0.95 that is 4 mm for the Panda's 0.1 kg fingers at 20 N and 1 mm/N for
    # the PR2's 20 g ones; at 0.9999, MuJoCo's stiffest, 8 um and 2 um/N, less than
    # PyBullet's own PR2 fingers sink at 20 N (0.14 mm; its limits are hard otherwise).
    joint.solref_limit, joint.solimp_limit = list(DRIVE_SOLREF), list(DRIVE_SOLIMP)
    body = joint.parent
    drive = body.parent.add_body(name=name + '/drive', pos=list(body.pos),
                                 quat=list(body.quat), mass=DRIVE_MASS,
                                 inertia=[1e-6] * 3, ipos=[0.0, 0.0, 0.0],
                                 iquat=[1.0, 0.0, 0.0, 0.0], explicitinertial=True)
    drive.add_joint(name=name + '/drive', type=joint.type, axis=list(joint.axis),
                    pos=list(joint.pos), armature=DRIVE_ARMATURE)
    tendon = world.spec.add_tendon(name=name + '/drive', frictionloss=float(force),
                                   solimp_friction=list(DRIVE_SOLIMP),
                                   solref_friction=list(DRIVE_SOLREF))
    tendon.wrap_joint(name, 1.0)
    tendon.wrap_joint(name + '/drive', -1.0)


def _parked_orientation() -> tuple[float, float, float, float]:
    """The palm turned so that the tool (its fingers, the palm's -x) points along +x, as
    the PyBullet model parks it (robots/gantry.py)."""
    from projection_server.simulation.engines.mujoco.physics import MujocoPhysics as P

    tool = ((0.0, 0.0, 0.0), P.quaternion_from_euler((0.0, -math.pi / 2, 0.0)))
    return P.multiply_transforms((0.0, 0.0, 0.0), P.quaternion_from_euler(
        (0.0, math.pi / 2, 0.0)), *P.invert_transform(*tool))[1]


def _park(physics: MujocoPhysics, entity: Entity, hand: Any, model: Any, prefix: str,
          spec_data: dict[str, Any], limits: dict[str, float]) -> None:
    """The free gripper as a manipulator, parked above the robot's pose, open."""
    from projection_server.simulation.engines.mujoco.physics import (MujocoFloatingTool,
                                                                   MujocoPhysics as P)
    from projection_server.simulation.robots.gantry import OPEN_WIDTH

    tool = ((0.0, 0.0, 0.0), P.quaternion_from_euler((0.0, -math.pi / 2, 0.0)))
    if math.isinf(hand.max_opening):   # no gripper entity: the fingers' own travel
        hand.max_opening = float(sum(model.jnt_range[j][1] for j in hand.fingers))
    opening = min(hand.max_opening, OPEN_WIDTH)
    data = physics.data
    mujoco.mj_kinematics(model, data)   # the parked pose, which the tool starts from
    for joint in (*hand.fingers, *hand._drives):
        data.qpos[model.jnt_qposadr[joint]] = opening / 2
    hand.open(opening, speed=0.1)
    reach = tuple(tuple(r) for r in spec_data['free_reach'])
    root = model.body(entity.name).id
    physics.manipulators[entity.name] = MujocoFloatingTool(
        physics, entity.name, root, hand, tool, entity.pose.xyz, reach,
        int(model.body_mocapid[model.body(prefix + 'target').id]))


BULLET_FRICTION = 0.5   # Bullet's lateral friction of a link whose URDF gives none


def _urdf_frictions(path: Path) -> dict[str, float]:
    """Link name -> the ``<contact><lateral_friction value>`` its URDF gives."""
    import xml.etree.ElementTree as ET

    out = {}
    for link in ET.parse(path).getroot().iter('link'):
        element = link.find('contact/lateral_friction')
        if element is not None:
            out[link.get('name')] = float(element.get('value'))
    return out


def _subtree(body: Any) -> list[Any]:
    """The bodies below ``body``, depth first (parents before children)."""
    out = []
    for child in body.bodies:
        out.append(child)
        out += _subtree(child)
    return out


_OBJECTS = {'environment': environment, 'floor': floor, 'table': table, 'egg': egg,
            'robot': robot, 'rigid_object': rigid_object}
def urdf(world: WorldSpec, entity: Entity, gripper: Entity | None = None) -> None:
    from projection_server.simulation.engines.mujoco.urdf import urdf_robot

    urdf_robot(world, entity, gripper)


_ROBOTS = {'pr2': pr2, 'urdf': urdf}


def object_builder(name: str) -> Callable[[WorldSpec, Entity], None] | None:
    """MuJoCo's builder of the object class ``name``; None if there is none."""
    return _OBJECTS.get(name)


def robot_builder(name: str) -> Callable[..., None] | None:
    """MuJoCo's builder of the robot model ``name``; None if there is none."""
    return _ROBOTS.get(name)
