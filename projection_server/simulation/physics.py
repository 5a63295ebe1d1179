"""A PyBullet world addressed by entity names: stepping, object models and named queries.

:class:`Physics` owns one ``BulletClient`` (never pybullet's module-global client), the
name <-> body registry built by :mod:`projection_server.simulation.world`, the grippers and
the object models that run after every physics step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import itertools
import math
from typing import Any, Callable, NamedTuple, Protocol, Sequence, TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError

if TYPE_CHECKING:
    from projection_server.settings import Settings
    from projection_server.simulation.scenario import Scenario

__all__ = [
    'Body',
    'Container',
    'ContactSample',
    'Fluid',
    'FrameRecorder',
    'Gripper',
    'GripperBase',
    'ObjectModel',
    'Pad',
    'Physics',
    'Shape',
    'bound_client',
]

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
_VELOCITY_GAINS = [1.0, 1.0]   # of the gantry's position motors (the speed fed forward)


@dataclass(frozen=True)
class Shape:
    """What a body looks like, for markers: kind, full extents along its own axes [m] and
    their orientation in the body's (or link's) frame."""

    kind: str                      # box, cylinder, sphere (scaled: ellipsoid), plane
    size: Vec3
    color: tuple[float, float, float, float] = (0.7, 0.7, 0.7, 1.0)
    orientation: Quat = (0.0, 0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        # Tuples of floats whatever an asset gives (YAML lists): a layout of shapes is the
        # monitor's cache key of its markers' template.
        for name in ('size', 'color', 'orientation'):
            object.__setattr__(self, name, tuple(map(float, getattr(self, name))))


@dataclass
class Body:
    """A simulated body registered under an entity name."""

    name: str
    cls: str
    body_id: int
    static: bool
    shape: Shape | None
    links: dict[int, str] = field(default_factory=dict)   # link index -> link name
    link_shapes: dict[int, list[tuple[Shape, Vec3]]] = field(default_factory=dict)  # + offset
    group: str | None = None   # the particle fluid this body is a particle of
    # A robot's: moved by its actuators, not by the world (it is not settled; its links
    # are logged as a chain under their parents).
    driven: bool = False
    urdf: str | None = None   # the path of the URDF it was loaded from (a robot's is logged)


@dataclass(frozen=True)
class Container:
    """The inside of an open container in its body frame: a cylinder of ``radius`` from
    ``bottom`` (z of the inner floor) up to ``rim`` [m]."""

    radius: float
    bottom: float
    rim: float


@dataclass
class Fluid:
    """A particle fluid: spheres of one ``radius`` [m], contacts reported under its name."""

    name: str
    radius: float
    body_ids: list[int]
    color: tuple[float, float, float, float] = (0.95, 0.9, 0.6, 1.0)


class _FluidState(NamedTuple):
    """A fluid's particles as read at step ``step`` (velocities None until asked for), and
    their positions one step before (None: not read then, or moved since)."""

    step: int
    positions: np.ndarray
    velocities: np.ndarray | None
    before: np.ndarray | None


@dataclass(frozen=True)
class Pad:
    """The flat contact face of a gripper finger, in its link frame.

    ``normal`` points out of the face (towards a grasped object); ``axes`` span the face;
    ``half_extents`` are the face's half sizes along ``axes``; ``stiffness`` is the
    foundation modulus of the pad's rubber layer [N/m^3] (E / thickness); ``rim_radius``
    the radius [m] to which the face's rim is rounded.
    """

    link: int
    link_name: str
    centre: Vec3
    normal: Vec3
    axes: tuple[Vec3, Vec3]
    half_extents: tuple[float, float]
    stiffness: float
    rim_radius: float


@dataclass(frozen=True)
class ContactSample:
    """A contact between two named bodies, aggregated over one link pair's manifold.

    Names are ordered so that ``(body_a, link_a) < (body_b, link_b)``; ``normal`` points
    from b to a; ``friction`` is the summed lateral friction force reported by Bullet.
    """

    body_a: str
    link_a: str
    body_b: str
    link_b: str
    position: Vec3
    normal: Vec3
    normal_force: float
    friction: Vec3


class ObjectModel(Protocol):
    """A controller attached to an object that computes what rigid-body physics does not."""

    name: str
    load: float   # equivalent load of the last step [N]

    def after_step(self, physics: Physics) -> None:
        """Run once after every physics step."""

    def sample(self) -> tuple[float, float, bool]:
        """``(load since the last sample [N], load limit [N] or 0, broken)``; resets the load."""


class GripperBase:
    """What every engine's gripper shares: its name and body, its pads, its joints
    (``joints``' ``fingers`` and, on a gantry, ``lift`` and ``approach``), the links that
    touch what it holds (``finger_links``, default: the pads' links), its limits and the
    command it was last given. An engine's gripper says how it moves the joints and what it
    measures (:meth:`state`)."""

    def __init__(self, name: str, body_id: int, joints: dict[str, Any], pads: list[Pad],
                 max_force: float = math.inf, max_opening: float = math.inf,
                 finger_links: Sequence[str] | None = None):
        self.name = name
        self.body_id = body_id
        self.pads = pads
        self._lift = joints.get('lift')
        self._approach = joints.get('approach')
        self._fingers = tuple(joints['fingers'])
        self._finger_links = (list(finger_links) if finger_links is not None
                              else [pad.link_name for pad in pads])
        self.max_force = max_force
        self.max_opening = max_opening
        self.command = 'open'
        self.commanded_force = 0.0

    @property
    def finger_links(self) -> list[str]:
        return self._finger_links

    @property
    def fingers(self) -> tuple[int, ...]:
        """The finger joints' indices."""
        return self._fingers

    def opening(self) -> float:
        """Distance between the pad faces [m]."""
        return self.state()[0]

    def measured_force(self) -> float:
        """Mean magnitude of the finger motors' forces [N]."""
        return self.state()[1]

    def state(self) -> tuple[float, float]:
        """``(opening, measured force)``, from one reading of the fingers."""
        raise NotImplementedError


class Gripper(GripperBase):
    """A parallel-jaw gripper, optionally on a gantry (lift along z, approach along x of its
    base frame).

    The fingers are force limited: closing drives them at a set speed with a motor whose force
    saturates at the commanded grip force, so once the pads touch an object they squeeze it
    with that force, at most ``max_force``; they open to at most ``max_opening``.
    Position control corrects ``tracking_rate`` [1/s] of its error per second, whatever the
    time step (Bullet's position gain is a fraction per step). ``joints`` has ``fingers``
    and, on a gantry, ``lift`` and ``approach``; ``finger_links`` are the links that touch
    what the gripper holds (default: the pads' links).
    """

    def __init__(self, client: Any, name: str, body_id: int, joints: dict[str, Any],
                 pads: list[Pad], max_joint_force: float, max_force: float = math.inf,
                 max_opening: float = math.inf, position_gain: float = 0.1,
                 finger_links: list[str] | None = None):
        super().__init__(name, body_id, joints, pads, max_force, max_opening, finger_links)
        self._client = client
        self._max_joint_force = max_joint_force
        self._gain = position_gain
        # What every move sends the gantry's joints but their targets (each step of a motion)
        self._gantry = [self._approach, self._lift]
        self._gantry_forces = [max_joint_force] * 2
        self._gantry_gains = [position_gain] * 2
        for j in self._fingers:   # velocity motors off until commanded
            self._client.setJointMotorControl2(body_id, j, self._client.VELOCITY_CONTROL,
                                               targetVelocity=0.0, force=0.0)

    def place(self, position: Vec3, orientation: Quat, approach: float, lift: float,
              opening: float) -> None:
        """Put the gantry base at a pose and the joints at given values (before a program)."""
        c = self._client
        c.resetBasePositionAndOrientation(self.body_id, position, orientation)
        c.resetJointState(self.body_id, self._approach, approach)
        c.resetJointState(self.body_id, self._lift, lift)
        for j in self._fingers:
            c.resetJointState(self.body_id, j, min(opening, self.max_opening) / 2)
        self.move(approach, lift)
        self.open(opening, speed=0.1)

    def move(self, approach: float, lift: float, approach_speed: float = 0.0,
             lift_speed: float = 0.0) -> None:
        """Position targets of the gantry joints [m], and the speeds [m/s] at which the
        targets move (fed forward: a target that moves smoothly is followed without lag)."""
        c = self._client
        c.setJointMotorControlArray(
            self.body_id, self._gantry, c.POSITION_CONTROL,
            targetPositions=[approach, lift], targetVelocities=[approach_speed, lift_speed],
            forces=self._gantry_forces, positionGains=self._gantry_gains,
            velocityGains=_VELOCITY_GAINS)

    def close(self, force: float, speed: float) -> None:
        """Close both fingers at ``speed`` [m/s], each pushing with at most ``force`` [N]
        (and at most the gripper's ``max_force``)."""
        force = min(force, self.max_force)
        self.command, self.commanded_force = 'close', force
        for j in self._fingers:
            self._client.setJointMotorControl2(self.body_id, j, self._client.VELOCITY_CONTROL,
                                               targetVelocity=-speed, force=force)

    def open(self, opening: float, speed: float) -> None:
        """Open the fingers to ``opening`` [m] between the pads (at most ``max_opening``)."""
        self.command, self.commanded_force = 'open', 0.0
        for j in self._fingers:
            self._client.setJointMotorControl2(
                self.body_id, j, self._client.POSITION_CONTROL,
                targetPosition=min(opening, self.max_opening) / 2, maxVelocity=speed,
                force=self._max_joint_force, positionGain=self._gain)

    def state(self) -> tuple[float, float]:
        """``(opening, measured force)`` from one query of the finger joints."""
        joints = self._client.getJointStates(self.body_id, self._fingers)
        forces = [abs(joint[3]) for joint in joints]
        return sum(joint[0] for joint in joints), sum(forces) / len(forces)

    def pad_faces(self) -> list[tuple[Pad, np.ndarray, np.ndarray, np.ndarray]]:
        """``(pad, face centre, face axes (2x3), face normal)`` of each pad in the world."""
        faces = []
        for pad in self.pads:
            state = self._client.getLinkState(self.body_id, pad.link,
                                              computeForwardKinematics=True)
            origin = np.asarray(state[4])
            rot = np.asarray(self._client.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            faces.append((pad, origin + rot @ pad.centre, (rot @ np.asarray(pad.axes).T).T,
                          rot @ pad.normal))
        return faces


def bound_client(connection_mode: int) -> Any:
    """A new ``BulletClient`` that binds each pybullet function to its physics client once.

    ``BulletClient`` makes a new ``functools.partial`` on every attribute access; this one
    keeps it, so that the calls of the step loop (about ten per physics step) cost a plain
    attribute lookup.
    """
    return _bound_client_class()(connection_mode=connection_mode)


@functools.cache
def _bound_client_class() -> type:
    from pybullet_utils.bullet_client import BulletClient

    class _BoundClient(BulletClient):
        def __getattr__(self, name: str) -> Any:
            attribute = super().__getattr__(name)
            setattr(self, name, attribute)
            return attribute

        def disconnect(self) -> None:
            import pybullet

            if self._client >= 0:
                pybullet.disconnect(physicsClientId=self._client)
                self._client = -1

    return _BoundClient


class Physics:
    """The simulation of one projection, with named access and queries: PyBullet's.

    What the monitor, the object models and the programs use of an engine is this class's
    protocol, which every engine implements (MuJoCo's:
    :class:`~projection_server.simulation.engines.mujoco.physics.MujocoPhysics`):

    * the registry (:attr:`bodies`, :attr:`grippers`, :attr:`models`, :meth:`name_of`,
      :meth:`link_name`), time (:meth:`step`, :meth:`step_unmonitored`, :attr:`time_ns`);
    * poses, as ``((x, y, z), (x, y, z, w))``: :meth:`pose` by name, ``base_pose(body)``,
      :meth:`link_poses` (a link's frame: its URDF frame), :meth:`frame_poses` (the
      monitor's frames, in one call), :meth:`frame_recorder` (the same frames, sample by
      sample, as arrays), :meth:`link_parent`, and the
      transform algebra :meth:`multiply_transforms`, :meth:`invert_transform`,
      :meth:`rotation_matrix`, :meth:`quaternion_from_euler`; ``base_velocity(body)``;
    * contacts: :meth:`contact_points` of a body in the last step, each a tuple of
      PyBullet's ``getContactPoints`` layout (flag, body a, body b, link a, link b, position
      on a, on b, normal from b to a, distance, normal force, friction 1, its direction,
      friction 2, its direction; a being the body asked for). Asked from the later-built
      body of a pair, the normal is turned round but the friction directions are not
      (Bullet's own order of the pair's bodies): an engine gives the same.
    """

    engine = 'pybullet'

    def after_copy(self) -> None:
        """Bind in a deep copy of this physics what the copy could not (an engine whose
        worlds copy: :class:`~projection_server.simulation.engines.Engine`)."""

    def __init__(self, client: Any, settings: Settings, scenario: Scenario | None = None,
                 tool_control: bool = False):
        self.client = client
        # Bound once: the monitor and the egg's model ask for them every step.
        if client is not None:
            self.base_pose = client.getBasePositionAndOrientation
            self.multiply_transforms = client.multiplyTransforms
            self.invert_transform = client.invertTransform
            self.quaternion_from_euler = client.getQuaternionFromEuler
            self.base_velocity = client.getBaseVelocity
        self.settings = settings
        self.scenario = scenario   # what the world is built from
        # Robots are built to have their tool moved (plans), not driven joint by joint.
        self.tool_control = tool_control
        self.manipulators: dict[str, Any] = {}   # robot name -> its Manipulator
        self.step_count = 0
        self.bodies: dict[str, Body] = {}
        self.grippers: dict[str, GripperBase] = {}
        self.models: list[ObjectModel] = []
        self.fluids: dict[str, Fluid] = {}
        self.containers: dict[str, Container] = {}
        self.shapes_changed = True   # markers must be (re)logged
        self.step_hooks: list[Callable[[], None]] = []   # run after every step's models
        self.bodies_version = 0   # changes whenever a body or fluid is added or replaced
        self._names: dict[int, str] = {}
        self._step_contacts: dict[int, Any] = {}   # body id -> its contact points this step
        # fluid -> its particles, read once per step however many step hooks and samples
        # want them
        self._fluid_states: dict[str, _FluidState] = {}
        # (bodies_version, {(body, link): (body name, link name)}) of contacts()
        self._frames: tuple[int, dict[tuple[int, int], tuple[str | None, str]]] = (-1, {})

    # --- registry -----------------------------------------------------------------------
    def add_body(self, body: Body) -> Body:
        if body.name in self.bodies:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'body {body.name!r} exists already')
        self.bodies[body.name] = body
        self._names[body.body_id] = body.group or body.name
        self.shapes_changed = True
        self.bodies_version += 1
        self._step_contacts = {}
        self._fluid_states = {}
        return body

    def add_fluid(self, fluid: Fluid) -> Fluid:
        """Register a fluid whose particles are bodies added with ``group`` = its name."""
        if fluid.name in self.bodies or fluid.name in self.fluids:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'body {fluid.name!r} exists already')
        self.fluids[fluid.name] = fluid
        self.bodies_version += 1
        self._step_contacts = {}
        self._fluid_states = {}
        return fluid

    def replace_body(self, name: str, body_id: int, shape: Shape) -> Body:
        """Swap the simulated body of ``name`` (e.g. an egg for its broken remains)."""
        old = self.bodies[name]
        self.client.removeBody(old.body_id)
        del self._names[old.body_id]
        new = Body(name, old.cls, body_id, old.static, shape)
        self.bodies[name] = new
        self._names[body_id] = name
        self.shapes_changed = True
        self.bodies_version += 1
        self._step_contacts = {}
        self._fluid_states = {}
        return new

    def body(self, name: str) -> Body:
        try:
            return self.bodies[name]
        except KeyError:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'no body named {name!r}') from None

    def name_of(self, body_id: int) -> str | None:
        return self._names.get(body_id)

    def link_name(self, body_id: int, link: int) -> str:
        body = self.bodies.get(self._names.get(body_id, ''))
        return body.links.get(link, '') if body is not None else ''

    # --- time ---------------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Simulated seconds since the start."""
        return self.step_count / self.settings.physics.rate_hz

    @property
    def time_ns(self) -> int:
        """Simulated time in integer nanoseconds (exact: no accumulated float error)."""
        return self.step_count * 1_000_000_000 // self.settings.physics.rate_hz

    def step(self) -> None:
        """One physics step, then every object model and every step hook."""
        self.client.stepSimulation()
        self.step_count += 1
        self._step_contacts = {}
        for model in self.models:
            model.after_step(self)
        for hook in self.step_hooks:
            hook()

    def step_unmonitored(self, steps: int) -> None:
        """``steps`` engine steps without object models, hooks or the projection's clock
        (settling the world before a program starts)."""
        step = self.client.stepSimulation
        for _ in range(steps):
            step()

    # --- named queries -----------------------------------------------------------------
    def pose(self, name: str) -> tuple[Vec3, Quat]:
        """World position and orientation (x, y, z, w) of a body's base."""
        return self.client.getBasePositionAndOrientation(self.body(name).body_id)

    def link_poses(self, body_id: int, links: list[int]) -> list[tuple[Vec3, Quat]]:
        """World frames of ``links`` of ``body_id``, in one query."""
        return [(state[4], state[5]) for state in
                self.client.getLinkStates(body_id, links, computeForwardKinematics=True)]

    def frame_poses(self, frames: list[tuple[int, list[int], list[tuple[int, int]] | None]]
                    ) -> list[tuple[Vec3, Quat]]:
        """The poses of ``frames``, each ``(body, links, chain)``: the body's base pose in
        the world, then its links' (``chain`` None) or, along ``chain`` (``(link, parent)``,
        parents first), each link's pose relative to its parent's (-1: the base)."""
        base_pose, link_poses = self.base_pose, self.link_poses
        multiply, invert = self.multiply_transforms, self.invert_transform
        poses: list[tuple[Any, Any]] = []
        for body_id, links, chain in frames:
            base = base_pose(body_id)
            poses.append(base)
            if not links:
                continue
            states = link_poses(body_id, links)
            if chain is None:
                poses += states
                continue
            world = {-1: base}
            inverse: dict[int, Any] = {}   # of a parent's world pose, once per call
            for (link, parent), pose in zip(chain, states):
                world[link] = pose
                inverted = inverse.get(parent)
                if inverted is None:
                    inverted = inverse[parent] = invert(*world[parent])
                poses.append(multiply(*inverted, *pose))
        return poses

    def frame_recorder(self, frames: list[tuple[int, list[int], list[tuple[int, int]] | None]]
                       ) -> FrameRecorder:
        """A :class:`FrameRecorder` of :meth:`frame_poses` of ``frames``."""
        return FrameRecorder(self, frames)

    def link_parent(self, body_id: int, link: int) -> int:
        """The link's parent link (-1: the base)."""
        return self.client.getJointInfo(body_id, link)[16]

    def rotation_matrix(self, quaternion: Quat) -> np.ndarray:
        """The 3x3 rotation of a quaternion (x, y, z, w)."""
        return np.asarray(self.client.getMatrixFromQuaternion(quaternion)).reshape(3, 3)

    def link_pose(self, name: str, link: int) -> tuple[Vec3, Quat]:
        state = self.client.getLinkState(self.body(name).body_id, link,
                                         computeForwardKinematics=True)
        return state[4], state[5]

    def contact_points(self, body_id: int) -> Any:
        """PyBullet's contact points of ``body_id`` (as ``bodyA``) in the last step; asked
        once per step and body, however many models and hooks want them."""
        points = self._step_contacts.get(body_id)
        if points is None:
            points = self._step_contacts[body_id] = self.client.getContactPoints(
                bodyA=body_id)
        return points

    def contact_points_of(self, body_ids: list[int]) -> list[Any]:
        """:meth:`contact_points` of each of ``body_ids``, in one call."""
        cached, query = self._step_contacts, self.client.getContactPoints
        out = []
        for body_id in body_ids:
            points = cached.get(body_id)
            if points is None:
                points = cached[body_id] = query(bodyA=body_id)
            out.append(points)
        return out

    def contact_force(self, a: str, b: str) -> float:
        """Total normal force between bodies ``a`` and ``b`` [N]."""
        return sum(p[9] for p in self.client.getContactPoints(
            bodyA=self.body(a).body_id, bodyB=self.body(b).body_id))

    def object_load(self, name: str) -> float:
        """Current equivalent load that the object model of ``name`` computed [N]."""
        for model in self.models:
            if model.name == name:
                return model.load
        raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'{name!r} has no object model')

    def particle_positions(self, fluid: str) -> np.ndarray:
        """World positions of a fluid's particles, shape (n, 3) [m]."""
        return self.particle_state(fluid)[0]

    def particle_state(self, fluid: str, velocities: bool = False
                       ) -> tuple[np.ndarray, np.ndarray | None]:
        """``(positions, velocities)`` of a fluid's particles, shapes (n, 3) [m, m/s], read
        once per step (velocities None unless asked for). Do not change them.

        When the positions were also read one step before (as the batter's hooks do each
        step), the velocities are the positions' change over the step, not read: Bullet
        moves a multibody's base by its new velocity times the step and corrects no
        position after, so the two agree to rounding (``test_pour`` checks it over a pour),
        and the 300 ``getBaseVelocity`` calls were 5 % of a pour. Code that moves
        particles between steps must call :meth:`particles_moved`."""
        state = self._fluid_states.get(fluid)
        if state is None or state.step != self.step_count:
            get = self.client.getBasePositionAndOrientation
            positions = _rows([get(i)[0] for i in self.fluids[fluid].body_ids])
            # Never from positions read at step 0: the world settles and the task may place
            # the particles after them.
            before = (state.positions if state is not None and state.step >= 1
                      and state.step == self.step_count - 1 else None)
            state = self._fluid_states[fluid] = _FluidState(self.step_count, positions, None,
                                                            before)
        if velocities and state.velocities is None:
            if state.before is not None:
                speeds = (state.positions - state.before) * self.settings.physics.rate_hz
            else:
                get = self.client.getBaseVelocity
                speeds = _rows([get(i)[0] for i in self.fluids[fluid].body_ids])
            state = self._fluid_states[fluid] = state._replace(velocities=speeds)
        return state.positions, state.velocities

    def particles_moved(self) -> None:
        """Forget the particles' positions read so far: they were moved, not stepped."""
        self._fluid_states = {}

    def gripper_opening(self, gripper: str) -> float:
        return self.grippers[gripper].opening()

    def contacts(self) -> list[ContactSample]:
        """All contacts of the last step between named bodies, one per link pair, sorted."""
        groups: dict[tuple[str, str, str, str], list[tuple[Any, float]]] = {}
        if self._frames[0] != self.bodies_version:
            self._frames = (self.bodies_version, {})
        frames = self._frames[1]   # (body, link) -> names, kept while the bodies are
        fluids = self.fluids
        for point in self._contact_points():
            key_a = frames.get((point[1], point[3]))
            if key_a is None:
                key_a = frames[(point[1], point[3])] = (
                    self.name_of(point[1]), self.link_name(point[1], point[3]))
            key_b = frames.get((point[2], point[4]))
            if key_b is None:
                key_b = frames[(point[2], point[4])] = (
                    self.name_of(point[2]), self.link_name(point[2], point[4]))
            a, b = key_a[0], key_b[0]
            if a is None or b is None or (a == b and a in fluids):
                continue
            sign = 1.0 if key_a < key_b else -1.0
            key = (*key_a, *key_b) if sign > 0 else (*key_b, *key_a)
            groups.setdefault(key, []).append((point, sign))
        samples = []
        for key in sorted(groups):
            points = groups[key]
            # Element by element the arithmetic of a loop over the points; the sums over
            # them in their order (cumsum from zero, as sum() adds).
            signs = np.array([s for _, s in points])[:, None]
            forces = np.array([p[9] for p, _ in points])
            total = float(forces.sum())
            positions = (np.array([p[5] for p, _ in points])
                         + np.array([p[6] for p, _ in points])) / 2
            weights = forces / total if total > 0 else np.full(len(points), 1 / len(points))
            normal = _sequential_sum(signs * np.array([p[7] for p, _ in points])
                                     * weights[:, None])
            norm = np.linalg.norm(normal)
            friction = _sequential_sum(signs * (
                np.array([p[10] for p, _ in points])[:, None]
                * np.array([p[11] for p, _ in points])
                + np.array([p[12] for p, _ in points])[:, None]
                * np.array([p[13] for p, _ in points])))
            samples.append(ContactSample(
                *key, position=tuple(weights @ positions),
                normal=tuple(normal / norm) if norm > 0 else (0.0, 0.0, 1.0),
                normal_force=total, friction=tuple(friction)))
        return samples

    def _contact_points(self) -> list[Any]:
        """The contact points of the last step, but none between two particles of a fluid.

        Those are most of a pour's points and are never reported; with one fluid the points
        are asked for body by body, for every body that is not one of its particles (a pair
        of two such bodies once, from its lower id). Bullet keeps a pair's bodies in the
        order they were created; asked from the later one, PyBullet turns the normal round
        but not the friction directions, so those are turned here.
        """
        if len(self.fluids) != 1:
            return self.client.getContactPoints()
        particles = set(next(iter(self.fluids.values())).body_ids)
        others = sorted(b for b in self._names if b not in particles)
        solid = set(others)
        points = []
        for body in others:
            for p in self.contact_points(body):   # a moving body's: asked this step already
                if p[2] < body:
                    if p[2] in solid:
                        continue
                    p = (*p[:11], tuple(-x for x in p[11]), p[12], tuple(-x for x in p[13]))
                points.append(p)
        return points


class FrameRecorder:
    """The poses of a monitor's frames (:meth:`Physics.frame_poses` of ``frames``), taken
    at each :meth:`add` and handed over as arrays by :meth:`take`: what an engine can read
    cheaply in a step (a copy of its pose arrays) it reads then, and what it can do for
    many samples at once (the links' poses relative to their parents) it does in
    :meth:`take`. This one asks :meth:`Physics.frame_poses` at each sample."""

    def __init__(self, physics: Physics, frames: list[tuple[int, list[int], Any]]):
        self._frame_poses = physics.frame_poses
        self._frames = frames
        self._rows: list[list[tuple[Vec3, Quat]]] = []

    def add(self) -> None:
        """The frames' poses now."""
        self._rows.append(self._frame_poses(self._frames))

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        """``(positions (n, k, 3), quaternions (n, k, 4))`` of the k frames in the n
        samples added since the last call, the numbers :meth:`Physics.frame_poses` gave."""
        rows, self._rows = self._rows, []
        n = len(rows)
        k = len(rows[0]) if rows else 0
        poses = [pose for row in rows for pose in row]
        positions = np.fromiter(itertools.chain.from_iterable([p for p, _ in poses]), float,
                                count=n * k * 3).reshape(n, k, 3)
        quaternions = np.fromiter(itertools.chain.from_iterable([q for _, q in poses]),
                                  float, count=n * k * 4).reshape(n, k, 4)
        return positions, quaternions


def _sequential_sum(rows: np.ndarray) -> np.ndarray:
    """``sum(rows)``: 0 + row 0 + row 1 + ..., added in that order."""
    return np.cumsum(np.vstack([np.zeros((1, rows.shape[1])), rows]), axis=0)[-1]


def _rows(vectors: list[tuple[float, float, float]]) -> np.ndarray:
    """An (n, 3) array of ``vectors`` (half the time of ``np.array`` on a list of tuples)."""
    return np.fromiter(itertools.chain.from_iterable(vectors), float,
                       3 * len(vectors)).reshape(len(vectors), 3)
