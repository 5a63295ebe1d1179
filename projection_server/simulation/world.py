"""The one builder from a scenario description to a PyBullet world.

Every physical property comes from the scenario (see
:data:`projection_server.simulation.scenario.PROPERTIES` for names, defaults and units) or
from an asset file; the engine's own settings come from ``config/physics.yaml``.

How each class becomes bodies (poses are world poses of the object's centre unless said):

* ``environment``: a container; its parts are built in its place. Its ``gravity`` (m/s^2,
  along -z) is the world's; without it, ``config/physics.yaml``'s gravity holds.
* ``floor``: a static plane at the pose's z.
* ``table``: a static slab ``size_x`` x ``size_y`` x ``size_z`` whose top is at ``height``
  (default: the pose's z), centred at the pose's x, y, turned by its yaw. Legs are not built.
* ``robot``: the gripper asset named by ``gripper`` (``assets/<name>.urdf`` + ``.yaml``),
  parked 1 m above the pose; control programs move it. No arm is simulated.
* ``egg``: a convex ellipsoid, long axis (``length``) along its x, with the
  :class:`~projection_server.simulation.object_models.EggShell` object model.
* ``cup``: an open container, a compound of a bottom disc (``wall_thickness`` thick) and
  :data:`CUP_SEGMENTS` wall boxes on a circle, ``radius`` and ``height`` outside; its inside
  is registered in :attr:`Physics.containers`.
* ``pancake_maker``: a flat disc (``radius``, ``height``); ``spatula``: a box (the blade;
  the turning program moves it as a hand would, so no handle or arm is simulated).
  Bodies with ``mass`` 0 are static.
* ``pancake``: a deformable body of jointed segments
  (:func:`projection_server.simulation.pancake.build_pancake`).
* ``particle_fluid``: ``particle_count`` spheres, registered as one :class:`Fluid` (contacts
  are reported under the fluid's name), their velocities damped by the fluid's ``damping``
  (viscosity: Bullet decelerates a particle by ``damping * v * (1 + |v|)``). With a
  ``container`` they fill its inside from the bottom in hexagonal layers; without one they
  form a cubic block at the pose.
"""

from __future__ import annotations

import functools
from importlib import resources
import math
from pathlib import Path
from typing import Any, Callable, TYPE_CHECKING
import xml.etree.ElementTree as ET

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.object_models import EggShell
from projection_server.simulation.pancake import build_pancake
from projection_server.simulation.physics import (
    Body, Container, Fluid, Gripper, Pad, Physics, Shape)

if TYPE_CHECKING:
    from projection_server.simulation.scenario import Entity, Scenario
    from projection_server.settings import PhysicsSettings, Settings

__all__ = ['assets_dir', 'build_world', 'ellipsoid_vertices', 'settle']

PARK_HEIGHT = 1.0   # m above the robot's pose, out of the way until a program moves it
EGG_COLOR = (0.95, 0.9, 0.8, 1.0)
REMAINS_COLOR = (0.95, 0.75, 0.2, 1.0)
REMAINS_FLATNESS = 0.3   # height of a broken egg's remains relative to its diameter
CUP_SEGMENTS = 16        # wall boxes of a cup
PARTICLE_GAP = 1.05      # spacing of spawned particles relative to their diameter
SPAWN_CLEARANCE = 1e-4   # m left between a spawned egg and what it would otherwise touch
SETTLE_CHECK = 0.01      # s of settling between checks whether the world is at rest
SETTLE_MIN, SETTLE_MAX = 0.1, 1.0   # s of settling at least and at most
TRACKING_RATE = 24.0     # 1/s: position control's error correction (0.1 per step at 240 Hz)
REST_SPEED = 1e-3        # m/s (and rad/s per 0.1 m) below which a body is at rest


def assets_dir() -> Path:
    """Directory of the simulation's data files (URDF, gripper descriptions)."""
    return Path(str(resources.files('projection_server.simulation').joinpath('assets')))


def build_world(client: Any, scenario: Scenario, settings: Settings) -> Physics:
    """Configure ``client`` from ``settings`` and build every entity of ``scenario`` in it."""
    _configure(client, settings.physics)
    physics = Physics(client, settings)
    grippers = {e.name: e for e in scenario.entities if e.cls == 'gripper'}
    for entity in scenario.entities:
        if entity.cls == 'robot':
            _build_robot(physics, entity, grippers.get(entity.properties['gripper']))
        elif entity.cls != 'gripper':   # grippers are built by their robot
            _BUILDERS[entity.cls](physics, entity)
    return physics


def settle(physics: Physics) -> float:
    """Let the world come to rest before a program starts; returns the seconds it took.

    The engine is stepped without object models and without advancing the projection's
    clock, for at least :data:`SETTLE_MIN` and until every moving body is slower than
    :data:`REST_SPEED` (at most :data:`SETTLE_MAX`), so that every projection starts from
    a world at rest whatever its time step: contacts of bodies spawned onto each other
    carry their weights, not a recovery from a spawn.
    """
    c = physics.client
    rate = physics.settings.physics.rate_hz
    chunk = max(1, round(SETTLE_CHECK * rate))
    moving = [b.body_id for b in physics.bodies.values()
              if not b.static and b.cls != 'robot']
    steps = 0
    while steps < SETTLE_MAX * rate:
        for _ in range(chunk):
            c.stepSimulation()
        steps += chunk
        if steps >= SETTLE_MIN * rate and all(_at_rest(c, body) for body in moving):
            break
    return steps / rate


def _at_rest(client: Any, body_id: int) -> bool:
    linear, angular = client.getBaseVelocity(body_id)
    return (math.hypot(*linear) < REST_SPEED
            and 0.1 * math.hypot(*angular) < REST_SPEED)


def _lift_clear(physics: Physics, body_id: int) -> None:
    """Raise a newly spawned body out of any body it penetrates (a pose given as the
    nominal contact, e.g. an egg lying on the table, touches within Bullet's margins)."""
    c = physics.client
    for _ in range(4):
        depth = max((-p[8] for other in physics.bodies.values() if other.body_id != body_id
                     for p in c.getClosestPoints(body_id, other.body_id, SPAWN_CLEARANCE)),
                    default=-SPAWN_CLEARANCE)
        if depth <= -SPAWN_CLEARANCE:
            return
        position, orientation = c.getBasePositionAndOrientation(body_id)
        c.resetBasePositionAndOrientation(
            body_id, (position[0], position[1], position[2] + depth + SPAWN_CLEARANCE),
            orientation)


def ellipsoid_vertices(semi_axes: tuple[float, float, float],
                       segments: tuple[int, int]) -> list[tuple[float, float, float]]:
    """Vertices of an ellipsoid: rings along x (``segments[0]``, even so that the equator is
    a ring) of ``segments[1]`` points each, plus the two poles."""
    a, b, c = semi_axes
    rings, around = segments
    vertices = [(a, 0.0, 0.0), (-a, 0.0, 0.0)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        x, s = a * math.cos(theta), math.sin(theta)
        for j in range(around):
            phi = 2 * math.pi * j / around
            vertices.append((x, b * s * math.cos(phi), c * s * math.sin(phi)))
    return vertices


def _configure(client: Any, s: PhysicsSettings) -> None:
    client.resetSimulation()
    client.setPhysicsEngineParameter(
        fixedTimeStep=s.time_step, numSubSteps=0, numSolverIterations=s.solver_iterations,
        erp=s.erp, contactERP=s.contact_erp, frictionERP=s.friction_erp,
        contactBreakingThreshold=s.contact_breaking_threshold,
        solverResidualThreshold=s.solver_residual_threshold,
        deterministicOverlappingPairs=s.deterministic_overlapping_pairs)
    client.setGravity(*s.gravity)


def _orientation(client: Any, entity: Entity) -> tuple[float, ...]:
    return client.getQuaternionFromEuler(entity.pose.rpy)


def _surface(client: Any, body_id: int, props: dict[str, Any]) -> None:
    client.changeDynamics(body_id, -1, lateralFriction=props['friction'],
                          restitution=props['restitution'])


def _build_environment(physics: Physics, entity: Entity) -> None:
    """The world's gravity; its parts are entities of the scenario."""
    gravity = entity.properties.get('gravity')
    if gravity is not None:
        physics.client.setGravity(0.0, 0.0, -gravity)


def _build_floor(physics: Physics, entity: Entity) -> None:
    c = physics.client
    shape = c.createCollisionShape(c.GEOM_PLANE)
    body = c.createMultiBody(0.0, shape, -1, (0.0, 0.0, entity.pose.xyz[2]))
    _surface(c, body, entity.properties)
    physics.add_body(Body(entity.name, entity.cls, body, True,
                          Shape('box', (20.0, 20.0, 0.001), (0.5, 0.5, 0.5, 1.0))))


def _build_table(physics: Physics, entity: Entity) -> None:
    c, p = physics.client, entity.properties
    size = (p['size_x'], p['size_y'], p['size_z'])
    top = p.get('height', entity.pose.xyz[2])
    shape = c.createCollisionShape(c.GEOM_BOX, halfExtents=[s / 2 for s in size])
    position = (entity.pose.xyz[0], entity.pose.xyz[1], top - size[2] / 2)
    yaw = c.getQuaternionFromEuler((0.0, 0.0, entity.pose.rpy[2]))
    body = c.createMultiBody(0.0, shape, -1, position, yaw)
    _surface(c, body, p)
    physics.add_body(Body(entity.name, entity.cls, body, True,
                          Shape('box', size, (0.6, 0.4, 0.2, 1.0))))


def _build_robot(physics: Physics, entity: Entity, gripper: Entity | None = None) -> None:
    """The robot's gripper on its gantry; ``gripper`` is the gripper's own entity, if the
    scenario describes it (its friction and asset then come from there)."""
    c = physics.client
    asset = (Path(gripper.properties['urdf']).stem if gripper is not None
             else entity.properties['gripper'])
    spec = _gripper_spec(asset)
    urdf = assets_dir() / spec['urdf']
    x, y, z = entity.pose.xyz
    body_id = c.loadURDF(str(urdf), (x, y, z + PARK_HEIGHT), useFixedBase=True)
    joints, links = {}, {}
    for j in range(c.getNumJoints(body_id)):
        info = c.getJointInfo(body_id, j)
        joints[info[1].decode()] = j
        links[j] = info[12].decode()
    link_index = {name: j for j, name in links.items()}
    try:
        joint_map = {'lift': joints[spec['joints']['lift']],
                     'approach': joints[spec['joints']['approach']],
                     'fingers': [joints[n] for n in spec['joints']['fingers']]}
        boxes = _urdf_boxes(urdf)
        pads = [_pad(link_index[pad['link']], pad, boxes[pad['collision']],
                     float(spec['pad_stiffness']), float(spec['pad_rim_radius']))
                for pad in spec['pads']]
    except KeyError as exc:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'gripper asset {spec["urdf"]}: unknown name {exc}') from exc
    link_shapes: dict[int, list[tuple[Shape, tuple[float, float, float]]]] = {}
    for box in boxes.values():
        link_shapes.setdefault(link_index[box['link']], []).append(
            (Shape('box', box['size'], (0.3, 0.3, 0.35, 1.0)), box['origin']))
    limits = {'max_force': math.inf, 'max_opening': math.inf}
    if gripper is not None:
        limits = {key: gripper.properties[key] for key in limits}
        for link in range(-1, c.getNumJoints(body_id)):
            c.changeDynamics(body_id, link,
                             lateralFriction=float(gripper.properties['friction']),
                             restitution=float(gripper.properties['restitution']))
        for finger in joint_map['fingers']:   # the fingers' travel ends at max_opening
            c.changeDynamics(body_id, finger, jointUpperLimit=limits['max_opening'] / 2)
    body = physics.add_body(Body(entity.name, entity.cls, body_id, False, None,
                                 links=links, link_shapes=link_shapes))
    gain = min(1.0, TRACKING_RATE / physics.settings.physics.rate_hz)
    physics.grippers[entity.name] = Gripper(c, body.name, body_id, joint_map, pads,
                                            float(spec['gantry_force']), position_gain=gain,
                                            **limits)


@functools.cache
def _gripper_spec(name: str) -> dict[str, Any]:
    import yaml

    path = assets_dir() / f'{name}.yaml'
    if not path.is_file():
        raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'unknown gripper {name!r} (no {path.name})')
    return yaml.safe_load(path.read_text())


@functools.cache
def _urdf_boxes(path: Path) -> dict[str, dict[str, Any]]:
    """Named collision boxes of a URDF: link, origin and size."""
    boxes = {}
    for link in ET.parse(path).getroot().iter('link'):
        for collision in link.iter('collision'):
            box = collision.find('geometry/box')
            if box is None or not collision.get('name'):
                continue
            origin = collision.find('origin')
            xyz = origin.get('xyz', '0 0 0') if origin is not None else '0 0 0'
            boxes[collision.get('name')] = {
                'link': link.get('name'),
                'origin': tuple(float(v) for v in xyz.split()),
                'size': tuple(float(v) for v in box.get('size').split())}
    return boxes


def _pad(link: int, pad: dict[str, Any], box: dict[str, Any], stiffness: float,
         rim_radius: float) -> Pad:
    normal = np.asarray(pad['normal'], dtype=float)
    axis = int(np.argmax(np.abs(normal)))
    size = np.asarray(box['size'])
    centre = np.asarray(box['origin']) + normal * size[axis] / 2
    others = [i for i in range(3) if i != axis]
    axes = tuple(tuple(float(v) for v in np.eye(3)[i]) for i in others)
    return Pad(link, pad['link'], tuple(centre), tuple(normal), axes,
               (size[others[0]] / 2, size[others[1]] / 2), stiffness, rim_radius)


def _build_egg(physics: Physics, entity: Entity) -> None:
    c, p = physics.client, entity.properties
    semi_axes = (p['length'] / 2, p['diameter'] / 2, p['diameter'] / 2)
    body = _ellipsoid_body(physics, semi_axes, p['mass'], entity.pose.xyz,
                           _orientation(c, entity))
    _surface(c, body, p)
    c.changeDynamics(body, -1, rollingFriction=p['rolling_friction'],
                     spinningFriction=p['spinning_friction'])
    _lift_clear(physics, body)
    physics.add_body(Body(entity.name, entity.cls, body, False,
                          Shape('sphere', tuple(2 * s for s in semi_axes), EGG_COLOR)))
    physics.models.append(EggShell(entity.name, semi_axes, p.get('breaking_force'),
                                   _remains_factory(semi_axes, p)))


def _ellipsoid_body(physics: Physics, semi_axes: tuple[float, float, float], mass: float,
                    position: Any, orientation: Any) -> int:
    c = physics.client
    vertices = ellipsoid_vertices(semi_axes, physics.settings.physics.ellipsoid_segments)
    shape = c.createCollisionShape(c.GEOM_MESH, vertices=vertices)
    body = c.createMultiBody(mass, shape, -1, position, orientation)
    a, b, cc = semi_axes
    # Bullet derives a hull's inertia from its bounding box; set the ellipsoid's own.
    c.changeDynamics(body, -1, localInertiaDiagonal=[mass * (b * b + cc * cc) / 5,
                                                     mass * (a * a + cc * cc) / 5,
                                                     mass * (a * a + b * b) / 5])
    return body


def _remains_factory(semi_axes: tuple[float, float, float],
                     props: dict[str, Any]) -> Callable[[Physics, str], None]:
    """How a broken egg is replaced: a flat, spilled body of the same mass that the gripper's
    pads no longer hold, where the egg was (its bottom where the egg's lowest point was),
    falling on if the egg broke in the air, at rest if it broke against something."""
    def replace(physics: Physics, name: str) -> None:
        c = physics.client
        old = physics.body(name).body_id
        position, orientation = c.getBasePositionAndOrientation(old)
        velocity = (c.getBaseVelocity(old)[0] if not c.getContactPoints(bodyA=old)
                    else (0.0, 0.0, 0.0))
        bottom = c.getAABB(old)[0][2]
        yaw = c.getEulerFromQuaternion(orientation)[2]
        flat = (semi_axes[0], semi_axes[1], semi_axes[2] * REMAINS_FLATNESS)
        flat_orientation = c.getQuaternionFromEuler((0.0, 0.0, yaw))
        body = _ellipsoid_body(physics, flat, props['mass'],
                               (position[0], position[1], bottom + flat[2]), flat_orientation)
        lowest = c.getAABB(body)[0][2]   # the same collision margin as the egg's
        c.resetBasePositionAndOrientation(
            body, (position[0], position[1], bottom + flat[2] + bottom - lowest),
            flat_orientation)
        _surface(c, body, props)
        c.resetBaseVelocity(body, velocity, (0.0, 0.0, 0.0))
        for gripper in physics.grippers.values():
            for link in range(-1, c.getNumJoints(gripper.body_id)):
                c.setCollisionFilterPair(body, gripper.body_id, -1, link, 0)
        physics.replace_body(name, body, Shape('sphere', tuple(2 * s for s in flat),
                                               REMAINS_COLOR))
    return replace


def _primitive(physics: Physics, entity: Entity, kind: str, size: tuple[float, float, float],
               color: tuple[float, float, float, float]) -> None:
    c, p = physics.client, entity.properties
    if kind == 'box':
        shape = c.createCollisionShape(c.GEOM_BOX, halfExtents=[s / 2 for s in size])
    else:
        shape = c.createCollisionShape(c.GEOM_CYLINDER, radius=size[0] / 2, height=size[2])
    mass = p['mass']
    body = c.createMultiBody(mass, shape, -1, entity.pose.xyz, _orientation(c, entity))
    _surface(c, body, p)
    physics.add_body(Body(entity.name, entity.cls, body, mass == 0.0,
                          Shape(kind if kind == 'box' else 'cylinder', size, color)))


def _build_disc(physics: Physics, entity: Entity) -> None:
    p = entity.properties
    _primitive(physics, entity, 'cylinder', (2 * p['radius'], 2 * p['radius'], p['height']),
               (0.2, 0.2, 0.2, 1.0))


def _build_cup(physics: Physics, entity: Entity) -> None:
    """An open cup: bottom disc and wall boxes in one compound body, origin at its centre."""
    c, p = physics.client, entity.properties
    radius, height, wall = p['radius'], p['height'], p['wall_thickness']
    if wall >= radius or wall >= height:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: wall_thickness must be below radius and height')
    half_angle = math.pi / CUP_SEGMENTS
    mid = radius - wall / 2
    types, radii, extents, lengths, positions, orientations = [], [], [], [], [], []
    types.append(c.GEOM_CYLINDER)
    radii.append(radius)
    extents.append([0.0, 0.0, 0.0])
    lengths.append(wall)
    positions.append([0.0, 0.0, -height / 2 + wall / 2])
    orientations.append([0.0, 0.0, 0.0, 1.0])
    for k in range(CUP_SEGMENTS):
        phi = 2 * half_angle * k
        types.append(c.GEOM_BOX)
        radii.append(0.0)
        # Tangential half length reaches the outer circle's chord, so the wall has no gaps.
        extents.append([wall / 2, radius * math.tan(half_angle), height / 2])
        lengths.append(0.0)
        positions.append([mid * math.cos(phi), mid * math.sin(phi), 0.0])
        orientations.append(list(c.getQuaternionFromEuler((0.0, 0.0, phi))))
    shape = c.createCollisionShapeArray(
        types, radii=radii, halfExtents=extents, lengths=lengths,
        collisionFramePositions=positions, collisionFrameOrientations=orientations)
    body = c.createMultiBody(p['mass'], shape, -1, entity.pose.xyz, _orientation(c, entity))
    _surface(c, body, p)
    physics.add_body(Body(entity.name, entity.cls, body, p['mass'] == 0.0,
                          Shape('cylinder', (2 * radius, 2 * radius, height),
                                (0.9, 0.9, 0.95, 0.4))))
    physics.containers[entity.name] = Container(radius - wall, -height / 2 + wall, height / 2)


def _build_spatula(physics: Physics, entity: Entity) -> None:
    p = entity.properties
    _primitive(physics, entity, 'box', (p['size_x'], p['size_y'], p['size_z']),
               (0.5, 0.5, 0.55, 1.0))


def _build_particle_fluid(physics: Physics, entity: Entity) -> None:
    c, p = physics.client, entity.properties
    count, radius = int(p['particle_count']), p['particle_radius']
    container = p.get('container')
    if container is not None:
        if container not in physics.containers:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'{entity.name}: container {container!r} is not built '
                                  'before it or is not a container')
        positions = _container_filling(physics, container, count, radius)
    else:
        positions = _block(entity.pose.xyz, count, radius)
    shape = c.createCollisionShape(c.GEOM_SPHERE, radius=radius)
    fluid = physics.add_fluid(Fluid(entity.name, radius, []))
    for i, position in enumerate(positions):
        body = c.createMultiBody(p['particle_mass'], shape, -1, position)
        _surface(c, body, p)
        c.changeDynamics(body, -1, rollingFriction=p['rolling_friction'],
                         spinningFriction=p['spinning_friction'],
                         linearDamping=p['damping'], angularDamping=p['damping'])
        fluid.body_ids.append(body)
        physics.add_body(Body(f'{entity.name}_{i}', entity.cls, body, False, None,
                              group=entity.name))


def _block(centre: Any, count: int, radius: float) -> list[list[float]]:
    side = math.ceil(count ** (1 / 3))
    spacing = 2 * PARTICLE_GAP * radius
    offset = (side - 1) * spacing / 2
    return [[centre[k] + (n * spacing - offset) for k, n in
             enumerate((i % side, (i // side) % side, i // (side * side)))]
            for i in range(count)]


def _container_filling(physics: Physics, name: str, count: int,
                       radius: float) -> list[list[float]]:
    """World positions of ``count`` particles in hexagonal layers inside a container, from
    its floor up (layers above the rim if they do not fit)."""
    inside = physics.containers[name]
    spacing = 2 * PARTICLE_GAP * radius
    reach = inside.radius - radius * PARTICLE_GAP
    layer = []
    rows = int(reach // (spacing * math.sqrt(3) / 2))
    for j in range(-rows, rows + 1):
        y = j * spacing * math.sqrt(3) / 2
        shift = spacing / 2 if j % 2 else 0.0
        columns = int(reach // spacing) + 1
        for i in range(-columns, columns + 1):
            x = i * spacing + shift
            if x * x + y * y <= reach * reach:
                layer.append((x, y))
    if not layer:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'particles do not fit into {name!r}')
    position, orientation = physics.pose(name)
    rot = np.asarray(physics.client.getMatrixFromQuaternion(orientation)).reshape(3, 3)
    out = []
    for k in range(count):
        x, y = layer[k % len(layer)]
        z = inside.bottom + radius * PARTICLE_GAP + (k // len(layer)) * spacing
        out.append(list(np.asarray(position) + rot @ np.array([x, y, z])))
    return out


_BUILDERS: dict[str, Callable[[Physics, Entity], None]] = {
    'environment': _build_environment,
    'floor': _build_floor,
    'table': _build_table,
    'robot': _build_robot,
    'egg': _build_egg,
    'cup': _build_cup,
    'pancake_maker': _build_disc,
    'pancake': build_pancake,
    'spatula': _build_spatula,
    'particle_fluid': _build_particle_fluid,
}
