"""MuJoCo's implementation of the engine protocol (:class:`~projection_server.simulation.
physics.Physics`): a compiled ``MjModel`` and its ``MjData``, addressed by entity names.

An entity is one MuJoCo body (its ``body_id`` on the protocol); a robot's links are the
bodies below its root, addressed by their MuJoCo body ids (its root is link -1, as in
PyBullet). Poses are read from ``xpos``/``xquat`` (quaternions turned to (x, y, z, w));
contacts from ``data.contact`` and the constraint forces of the step, in the protocol's
layout of a contact point, once per step for every body.
"""

from __future__ import annotations

import itertools
import math
from typing import Any, Callable, TYPE_CHECKING

import mujoco
import numpy as np

from projection_server.simulation.physics import GripperBase, Physics, Shape
from projection_server.simulation.robots.manipulator import FloatingToolBase

if TYPE_CHECKING:
    from projection_server.settings import Settings
    from projection_server.simulation.physics import Body, Pad
    from projection_server.simulation.scenario import Scenario

__all__ = ['MujocoGripper', 'MujocoPhysics']

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
_FRICTION_TENDON = int(mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON)


class MujocoPhysics(Physics):
    """The simulation of one projection in MuJoCo (see the module doc)."""

    engine = 'mujoco'

    def __init__(self, model: Any, data: Any, settings: Settings,
                 scenario: Scenario | None = None, tool_control: bool = False):
        super().__init__(None, settings, scenario, tool_control)
        self.model, self.data = model, data
        # Run before every engine step: the motors' commands of that step.
        self.controllers: list[Callable[[], None]] = []
        self._owner: np.ndarray = np.zeros((0, 2), dtype=int)   # geom -> (body, link)
        self._owner_list: list[tuple[int, int]] = []
        self._points: dict[int, list[tuple[Any, ...]]] | None = None   # of this step
        self._free: dict[int, int] = {}   # body -> its free joint's first dof
        # The pose arrays, bound once: MjData's attributes make a new array on each access,
        # and indexing one with a list of rows costs several times reading it whole.
        self._xpos, self._xquat, self._xipos = data.xpos, data.xquat, data.xipos
        self._elliptic = model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
        # Every contact is one of the world's pairs (no geom collides by its own type bits)
        # and every pair has friction: each contact's dimension is known without reading it.
        self._frictional = bool(
            self._elliptic and not model.geom_contype.any() and not model.geom_conaffinity.any()
            and (model.pair_dim > 1).all())

    def bind(self) -> None:
        """Map every geom to its entity's body and link, once the bodies are registered."""
        model = self.model
        root = {}
        for body in self.bodies.values():
            root[body.body_id] = (body.body_id, -1)
            for link in body.links:
                root[link] = (body.body_id, link)
        owner = np.full((model.ngeom, 2), -2, dtype=int)
        for geom in range(model.ngeom):
            body = int(model.geom_bodyid[geom])
            while body not in root and body != 0:
                body = int(model.body_parentid[body])
            if body in root:
                owner[geom] = root[body]
        self._owner = owner
        self._owner_list = [tuple(row) for row in owner.tolist()]
        for body in self.bodies.values():
            joint = int(model.body_jntadr[body.body_id])
            if joint >= 0 and model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_FREE:
                self._free[body.body_id] = int(model.jnt_dofadr[joint])

    def after_copy(self) -> None:
        """Views into the copied MjData where the deep copy made arrays of their own."""
        data = self.data
        self._xpos, self._xquat, self._xipos = data.xpos, data.xquat, data.xipos
        for gripper in self.grippers.values():
            if isinstance(gripper, MujocoGripper):
                gripper._qpos_array, gripper._qvel_array = data.qpos, data.qvel

    # --- registry -----------------------------------------------------------------------
    def replace_body(self, name: str, body_id: int, shape: Shape) -> Body:
        """The body of ``name`` now has ``shape`` (its builder changed it in place: a
        compiled model keeps its bodies)."""
        old = self.bodies[name]
        old.shape = shape
        self.shapes_changed = True
        self.bodies_version += 1
        self._points = None
        return old

    # --- time ---------------------------------------------------------------------------
    def step(self) -> None:
        self._engine_step()
        self.step_count += 1
        for model in self.models:
            model.after_step(self)
        for hook in self.step_hooks:
            hook()

    def step_unmonitored(self, steps: int) -> None:
        for _ in range(steps):
            self._engine_step()

    def _engine_step(self) -> None:
        for control in self.controllers:
            control()
        mujoco.mj_step(self.model, self.data)
        self._points = None

    # --- poses ----------------------------------------------------------------------------
    def base_pose(self, body_id: int) -> tuple[Vec3, Quat]:
        """A body's base frame as PyBullet's: at its centre of mass, turned as its link."""
        w, x, y, z = self._xquat[body_id].tolist()
        return tuple(self._xipos[body_id].tolist()), (x, y, z, w)

    def pose(self, name: str) -> tuple[Vec3, Quat]:
        return self.base_pose(self.body(name).body_id)

    def link_pose(self, name: str, link: int) -> tuple[Vec3, Quat]:
        return self.base_pose(link)

    def link_poses(self, body_id: int, links: list[int]) -> list[tuple[Vec3, Quat]]:
        positions, quaternions = self._xpos.tolist(), self._xquat.tolist()
        out = []
        for link in links:
            w, x, y, z = quaternions[link]
            out.append((tuple(positions[link]), (x, y, z, w)))
        return out

    def frame_poses(self, frames: list[tuple[int, list[int], list[tuple[int, int]] | None]]
                    ) -> list[tuple[Vec3, Quat]]:
        """:meth:`Physics.frame_poses`, from one read of each pose array: the same
        poses as from ``base_pose``, ``link_poses`` and the transforms."""
        positions, quaternions = self._xpos.tolist(), self._xquat.tolist()
        centres = self._xipos.tolist()
        multiply, invert = self.multiply_transforms, self.invert_transform
        poses: list[tuple[Vec3, Quat]] = []
        for body_id, links, chain in frames:
            w, x, y, z = quaternions[body_id]
            base = (tuple(centres[body_id]), (x, y, z, w))
            poses.append(base)
            if chain is None:
                for link in links:
                    w, x, y, z = quaternions[link]
                    poses.append((tuple(positions[link]), (x, y, z, w)))
                continue
            world = {-1: base}
            inverse: dict[int, Any] = {}
            for link, parent in chain:
                w, x, y, z = quaternions[link]
                pose = world[link] = (tuple(positions[link]), (x, y, z, w))
                inverted = inverse.get(parent)
                if inverted is None:
                    inverted = inverse[parent] = invert(*world[parent])
                poses.append(multiply(*inverted, *pose))
        return poses

    def frame_recorder(self, frames: list[tuple[int, list[int], list[tuple[int, int]] | None]]
                       ) -> MujocoFrameRecorder:
        return MujocoFrameRecorder(self, frames)

    def link_parent(self, body_id: int, link: int) -> int:
        parent = int(self.model.body_parentid[link])
        return -1 if parent == body_id else parent

    def base_velocity(self, body_id: int) -> tuple[Vec3, Vec3]:
        dof = self._free.get(body_id)
        if dof is None:
            return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        v = self.data.qvel[dof:dof + 6].tolist()
        return tuple(v[:3]), tuple(v[3:])   # angular in the body's frame: its norm counts

    @staticmethod
    def multiply_transforms(p1: Vec3, q1: Quat, p2: Vec3, q2: Quat) -> tuple[Vec3, Quat]:
        # _rotate(q1, p2) and _multiply(q1, q2) written out (the monitor's frames, each
        # sample): the same operations in the same order.
        x, y, z, w = q1
        vx, vy, vz = p2
        cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
        dx, dy, dz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
        bx, by, bz, bw = q2
        return ((p1[0] + (vx + 2 * (w * cx + dx)), p1[1] + (vy + 2 * (w * cy + dy)),
                 p1[2] + (vz + 2 * (w * cz + dz))),
                (w * bx + x * bw + y * bz - z * by, w * by - x * bz + y * bw + z * bx,
                 w * bz + x * by - y * bx + z * bw, w * bw - x * bx - y * by - z * bz))

    @staticmethod
    def invert_transform(p: Vec3, q: Quat) -> tuple[Vec3, Quat]:
        # (-_rotate(c, p), c) of the conjugate c, written out.
        x, y, z, w = -q[0], -q[1], -q[2], q[3]
        vx, vy, vz = p
        cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
        dx, dy, dz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
        return ((-(vx + 2 * (w * cx + dx)), -(vy + 2 * (w * cy + dy)),
                 -(vz + 2 * (w * cz + dz))), (x, y, z, w))

    @staticmethod
    def rotation_matrix(quaternion: Quat) -> np.ndarray:
        x, y, z, w = quaternion
        out = np.empty(9)
        mujoco.mju_quat2Mat(out, np.array([w, x, y, z], dtype=float))
        return out.reshape(3, 3)

    @staticmethod
    def quaternion_from_euler(rpy: Any) -> Quat:
        """PyBullet's convention: roll about x, then pitch about y, then yaw about z, all
        about the fixed axes."""
        roll, pitch, yaw = (float(a) / 2 for a in rpy)
        cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch),
                                  math.sin(pitch), math.cos(yaw), math.sin(yaw))
        return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)

    # --- contacts ---------------------------------------------------------------------------
    def contact_points(self, body_id: int) -> list[tuple[Any, ...]]:
        points = self._points if self._points is not None else self._read_contacts()
        return points.get(body_id, [])

    def contact_points_of(self, body_ids: list[int]) -> list[Any]:
        points = self._points if self._points is not None else self._read_contacts()
        return [points.get(body_id, []) for body_id in body_ids]

    def contact_force(self, a: str, b: str) -> float:
        other = self.body(b).body_id
        return sum(p[9] for p in self.contact_points(self.body(a).body_id) if p[2] == other)

    def _contact_points(self) -> list[Any]:
        points = self._points if self._points is not None else self._read_contacts()
        return [p for body, ps in points.items() for p in ps if p[2] > body]

    def _read_contacts(self) -> dict[int, list[tuple[Any, ...]]]:
        """The step's contacts, each in the protocol's layout from either body. The contact
        frame's normal points from geom 1 to geom 2, and the force of the constraint
        (normal, then the two frictional components along the frame's tangents: an
        elliptic cone's rows in ``efc_force``) acts on geom 2. A step has a handful of
        contacts: plain floats cost less than numpy's overhead on them."""
        d = self.data
        n = d.ncon
        points: dict[int, list[tuple[Any, ...]]] = {}
        self._points = points
        if n == 0:
            return points
        contact = d.contact
        owner = self._owner_list
        elliptic = self._elliptic
        # The step's constraint forces as one list: a handful of numpy scalars cost more.
        efc = d.efc_force.tolist() if elliptic else None
        out = None if elliptic else np.zeros(6)
        dims = itertools.repeat(3) if self._frictional else contact.dim.tolist()
        for k, ((g1, g2), address, dim, frame, position, dist) in enumerate(zip(
                contact.geom.tolist(), contact.efc_address.tolist(), dims,
                contact.frame.tolist(), contact.pos.tolist(), contact.dist.tolist())):
            if address < 0:   # excluded: no constraint
                continue
            b1, l1 = owner[g1]
            b2, l2 = owner[g2]
            if b1 < 0 or b2 < 0 or b1 == b2:
                continue
            if elliptic:
                fn = efc[address]
                if dim > 1:
                    ft1, ft2 = efc[address + 1], efc[address + 2]
                else:
                    ft1, ft2 = 0.0, 0.0
            else:
                mujoco.mj_contactForce(self.model, d, k, out)
                fn, ft1, ft2 = float(out[0]), float(out[1]), float(out[2])
            nx, ny, nz, t1x, t1y, t1z, t2x, t2y, t2z = frame
            position = tuple(position)
            t1, t2 = (t1x, t1y, t1z), (t2x, t2y, t2z)
            # From the later body: the normal turned, the friction as it is (the protocol).
            if b1 < b2:   # a = geom 1's body: the normal from b to a is -n; a feels -f
                a, b = b1, b2
                ft1, ft2 = -ft1, -ft2
                point = (0, b1, b2, l1, l2, position, position, (-nx, -ny, -nz), dist, fn,
                         ft1, t1, ft2, t2)
                turned = (0, b2, b1, l2, l1, position, position, (nx, ny, nz), dist, fn,
                          ft1, t1, ft2, t2)
            else:
                a, b = b2, b1
                point = (0, b2, b1, l2, l1, position, position, (nx, ny, nz), dist, fn,
                         ft1, t1, ft2, t2)
                turned = (0, b1, b2, l1, l2, position, position, (-nx, -ny, -nz), dist, fn,
                          ft1, t1, ft2, t2)
            listed = points.get(a)
            if listed is None:
                points[a] = [point]
            else:
                listed.append(point)
            listed = points.get(b)
            if listed is None:
                points[b] = [turned]
            else:
                listed.append(turned)
        return points


class MujocoFrameRecorder:
    """:class:`~projection_server.simulation.physics.FrameRecorder` of MuJoCo's: a sample
    copies ``xipos`` (a base is at its centre of mass), ``xpos`` (a link) and ``xquat``;
    :meth:`take` picks the frames' rows of them and turns the links of a chain into poses relative to their
    parents for all samples at once, by the operations of :meth:`MujocoPhysics.
    frame_poses` in the same order, element-wise (the same numbers)."""

    def __init__(self, physics: MujocoPhysics, frames: list[tuple[int, list[int], Any]]):
        self._physics = physics
        entries: list[tuple[str, int]] = []   # the world poses read: (array, body id)
        index: dict[tuple[str, int], int] = {}

        def entry(kind: str, body: int) -> int:
            key = (kind, body)
            if key not in index:
                index[key] = len(entries)
                entries.append(key)
            return index[key]

        out: list[tuple[int, int]] = []   # per frame: (entry, parent's entry or -1)
        for body_id, links, chain in frames:
            base = entry('base', body_id)
            out.append((base, -1))
            if chain is None:
                out += [(entry('link', link), -1) for link in links]
                continue
            world = {-1: base}
            for link, parent in chain:
                world[link] = entry('link', link)
                out.append((world[link], world[parent]))
        bases = [body for kind, body in entries if kind == 'base']
        links = [body for kind, body in entries if kind == 'link']
        # Entries as read: the bases first, then the links.
        order = {key: i for i, key in enumerate([('base', b) for b in bases]
                                                + [('link', b) for b in links])}
        where = [order[key] for key in entries]
        self._bases, self._links = np.array(bases, dtype=int), np.array(links, dtype=int)
        self._quats = np.concatenate([self._bases, self._links])
        # (frames, their entries) of those in the world; (frames, entries, parents' entries)
        # of those relative to a parent.
        self._direct = [[j for j, (_, parent) in enumerate(out) if parent < 0],
                        [where[e] for e, parent in out if parent < 0]]
        self._relative = [[j for j, (_, parent) in enumerate(out) if parent >= 0],
                          [where[e] for e, parent in out if parent >= 0],
                          [where[parent] for _, parent in out if parent >= 0]]
        self._count = len(out)
        self._rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def add(self) -> None:
        # Whole arrays: a copy of each costs a fifth of picking the frames' rows of it.
        physics = self._physics
        self._rows.append((physics._xipos.copy(), physics._xpos.copy(),
                           physics._xquat.copy()))

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        rows, self._rows = self._rows, []
        n, k = len(rows), self._count
        positions, quaternions = np.empty((n, k, 3)), np.empty((n, k, 4))
        if not n or not k:
            return positions, quaternions
        world_p = np.concatenate([np.array([r[0] for r in rows])[:, self._bases],
                                  np.array([r[1] for r in rows])[:, self._links]], axis=1)
        # (w, x, y, z) -> (x, y, z, w)
        world_q = np.array([r[2] for r in rows])[:, self._quats][:, :, [1, 2, 3, 0]]
        frames, sources = self._direct
        positions[:, frames] = world_p[:, sources]
        quaternions[:, frames] = world_q[:, sources]
        frames, children, parents = self._relative
        if frames:
            p, q = _relative(world_p[:, parents], world_q[:, parents],
                             world_p[:, children], world_q[:, children])
            positions[:, frames] = p
            quaternions[:, frames] = q
        return positions, quaternions


def _relative(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """``multiply_transforms(*invert_transform(p1, q1), p2, q2)`` of each row (positions
    (..., 3), quaternions (..., 4)): their operations, element-wise, in their order."""
    x, y, z, w = -q1[..., 0], -q1[..., 1], -q1[..., 2], q1[..., 3]
    vx, vy, vz = p1[..., 0], p1[..., 1], p1[..., 2]
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    dx, dy, dz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    ix, iy, iz = -(vx + 2 * (w * cx + dx)), -(vy + 2 * (w * cy + dy)), -(vz + 2 * (w * cz + dz))
    vx, vy, vz = p2[..., 0], p2[..., 1], p2[..., 2]
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    dx, dy, dz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    bx, by, bz, bw = q2[..., 0], q2[..., 1], q2[..., 2], q2[..., 3]
    position = np.stack([ix + (vx + 2 * (w * cx + dx)), iy + (vy + 2 * (w * cy + dy)),
                         iz + (vz + 2 * (w * cz + dz))], axis=-1)
    quaternion = np.stack([w * bx + x * bw + y * bz - z * by, w * by - x * bz + y * bw + z * bx,
                           w * bz + x * by - y * bx + z * bw, w * bw - x * bx - y * by - z * bz],
                          axis=-1)
    return position, quaternion


class MujocoGripper(GripperBase):
    """:class:`~projection_server.simulation.physics.Gripper`'s commands on MuJoCo: the
    gantry's lift and approach and each finger's drive are joints of a large inertia that
    are set their speeds each step; a finger follows its drive through a tendon whose
    friction loss is the command's force limit (a velocity motor of bounded force, solved
    with the contacts, as PyBullet's motors are). Position control corrects ``tracking_rate`` [1/s] of its error a second, with
    the target's speed fed forward, as PyBullet's position motors do at their gain; the
    fingers close at a speed and then push with the grip force."""

    def __init__(self, physics: MujocoPhysics, name: str, body_id: int,
                 joints: dict[str, Any], actuators: dict[int, int], pads: list[Pad],
                 max_joint_force: float, max_force: float = math.inf,
                 max_opening: float = math.inf, tracking_rate: float = 24.0,
                 finger_links: list[str] | None = None, mocap: int = -1):
        super().__init__(name, body_id, joints, pads, max_force, max_opening, finger_links)
        self._physics = physics
        self._max_joint_force = max_joint_force
        self._rate = tracking_rate
        self._mocap = mocap
        model = physics.model
        self._drives = tuple(joints['drives'])
        self._tendons = np.array(joints['tendons'])
        self._finger_qpos = np.array([model.jnt_qposadr[j] for j in self._fingers])
        # The servos' joints: a finger is commanded through its drive.
        self._drive_of = dict(zip(self._fingers, self._drives))
        order = [j for j in (self._lift, self._approach, *self._drives) if j is not None]
        self._joints = np.array(order)
        self._qpos = np.array([model.jnt_qposadr[j] for j in order])
        self._dof = np.array([model.jnt_dofadr[j] for j in order])
        self._servos = 0   # every joint is set its speed (none is actuated)
        self._slot = {j: i for i, j in enumerate(order)}
        count = len(order)
        # Per joint: position target, fed-forward speed, speed limit (inf: none), position
        # control on (else the fed-forward speed is the command), force limit.
        self._qpos_list = self._qpos.tolist()
        self._dof_list = self._dof.tolist()
        self._target = physics.data.qpos[self._qpos].tolist()
        self._speed = [0.0] * count
        self._limit = [math.inf] * count
        self._servo = [True] * count
        self._force = [max_joint_force] * count
        # Bound once (MjData makes a new array on each access); qpos and qvel keep their
        # memory for the data's life.
        self._qpos_array, self._qvel_array = physics.data.qpos, physics.data.qvel
        self._finger_qpos_list = self._finger_qpos.tolist()
        self._tendon_list = self._tendons.tolist()
        self._applied: list[float] | None = None   # the tendons' friction losses last set
        self._apply_limits()
        physics.controllers.append(self._control)

    def _control(self) -> None:
        """The servos' velocity commands and the drives' speeds of the next step."""
        qpos, qvel = self._qpos_array.tolist(), self._qvel_array
        rate = self._rate
        for dof, address, target, speed, limit, servo in zip(
                self._dof_list, self._qpos_list, self._target, self._speed, self._limit,
                self._servo):
            if servo:
                speed = speed + rate * (target - qpos[address])
            qvel[dof] = -limit if speed < -limit else limit if speed > limit else speed

    def _apply_limits(self) -> None:
        forces = self._force[-len(self._drives):]
        if forces == self._applied:   # the gantry's targets move each step; the grip not
            return
        self._physics.model.tendon_frictionloss[self._tendons] = forces
        self._applied = forces

    def _set(self, joint: int, target: float | None, speed: float, limit: float,
             force: float) -> None:
        i = self._slot[self._drive_of.get(joint, joint)]
        self._servo[i] = target is not None
        if target is not None:
            self._target[i] = target
        self._speed[i], self._limit[i], self._force[i] = speed, limit, force

    def place(self, position: Vec3, orientation: Quat, approach: float, lift: float,
              opening: float) -> None:
        physics = self._physics
        model, data = physics.model, physics.data
        x, y, z, w = orientation
        data.mocap_pos[self._mocap] = position
        data.mocap_quat[self._mocap] = (w, x, y, z)
        half = min(opening, self.max_opening) / 2
        for joint, value in ((self._approach, approach), (self._lift, lift),
                             *((f, half) for f in (*self._fingers, *self._drives))):
            data.qpos[model.jnt_qposadr[joint]] = value
            data.qvel[model.jnt_dofadr[joint]] = 0.0
        mujoco.mj_forward(model, data)
        self.move(approach, lift)
        self.open(opening, speed=0.1)

    def move(self, approach: float, lift: float, approach_speed: float = 0.0,
             lift_speed: float = 0.0) -> None:
        force = self._max_joint_force
        self._set(self._approach, approach, approach_speed, math.inf, force)
        self._set(self._lift, lift, lift_speed, math.inf, force)
        self._apply_limits()

    def close(self, force: float, speed: float) -> None:
        force = min(force, self.max_force)
        self.command, self.commanded_force = 'close', force
        for j in self._fingers:
            self._set(j, None, -speed, math.inf, force)
        self._apply_limits()

    def open(self, opening: float, speed: float) -> None:
        self.command, self.commanded_force = 'open', 0.0
        for j in self._fingers:
            self._set(j, min(opening, self.max_opening) / 2, 0.0, speed,
                      self._max_joint_force)
        self._apply_limits()

    def state(self) -> tuple[float, float]:
        """``(opening, measured force)``: the fingers' joint values' sum, and the mean
        magnitude of their servos' forces."""
        data = self._physics.data
        n = len(self._fingers)
        qpos = self._qpos_array.tolist()
        # numpy's sum of a few: the first plus the sum of the others from 0.0
        first, *rest = self._finger_qpos_list
        others = 0.0
        for address in rest:
            others += qpos[address]
        opening = qpos[first] + others
        # What each finger is pushed with: its tendon's friction.
        # The friction rows follow the equality rows (MuJoCo's order of constraints).
        first, last = data.ne, data.ne + data.nf
        ids, forces = data.efc_id[first:last].tolist(), data.efc_force[first:last].tolist()
        kinds = data.efc_type[first:last].tolist()
        mine, tendon = self._tendon_list, _FRICTION_TENDON
        total = 0
        for i, f, k in zip(ids, forces, kinds):
            if k == tendon and i in mine:
                total += abs(f)
        return opening, total / n

    def pad_faces(self) -> list[tuple[Pad, np.ndarray, np.ndarray, np.ndarray]]:
        faces = []
        for pad in self.pads:
            ((origin, quaternion),) = self._physics.link_poses(self.body_id, [pad.link])
            rot = self._physics.rotation_matrix(quaternion)
            faces.append((pad, np.asarray(origin) + rot @ pad.centre,
                          (rot @ np.asarray(pad.axes).T).T, rot @ pad.normal))
        return faces


def _multiply(a: Quat, b: Quat) -> Quat:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def _rotate(q: Quat, v: Vec3) -> Vec3:
    x, y, z, w = q
    # v + 2 w (u x v) + 2 u x (u x v), u the vector part
    cx, cy, cz = y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]
    dx, dy, dz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    return (v[0] + 2 * (w * cx + dx), v[1] + 2 * (w * cy + dy), v[2] + 2 * (w * cz + dz))


class MujocoFloatingTool(FloatingToolBase):
    """A floating tool
    (:class:`~projection_server.simulation.robots.manipulator.FloatingToolBase`) on MuJoCo:
    the free gripper is welded to a mocap body that the plan's tool pose moves, softly (a weld's
    reference time constant of 1 / the tracking rate), so that the tool follows as
    PyBullet's moving constraint has it follow, and what it pushes pushes back."""

    def __init__(self, physics: MujocoPhysics, name: str, body_id: int, gripper: Any,
                 tool: tuple[Any, Any], home: Any, reach: tuple[tuple[float, float], ...],
                 mocap: int):
        super().__init__(name, body_id, gripper, home, reach)
        self._physics = physics
        self._tool = (tuple(tool[0]), tuple(tool[1]))
        self._link_in_tool = MujocoPhysics.invert_transform(*self._tool)
        self._mocap = mocap
        self.servo(*self.tool_pose())

    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        d = self._physics.data
        w, x, y, z = d.xquat[self.body_id].tolist()
        link = (tuple(d.xpos[self.body_id].tolist()), (x, y, z, w))
        position, orientation = MujocoPhysics.multiply_transforms(*link, *self._tool)
        return np.asarray(position), np.asarray(orientation)

    def _move(self, position: tuple[float, ...], orientation: tuple[float, ...]) -> None:
        link = MujocoPhysics.multiply_transforms(position, orientation, *self._link_in_tool)
        d = self._physics.data
        d.mocap_pos[self._mocap] = link[0]
        x, y, z, w = link[1]
        d.mocap_quat[self._mocap] = (w, x, y, z)
