"""Monitoring: turns the state of a :class:`Physics` into bag messages (topics: ``bags``).

Contacts are not sampled but aggregated: every physics step's contacts (of every body but a
fluid's particles) are summed per link pair, and a sample reports each pair that touched in
any step since the last sample, with its impulse over the sample period as the normal force
(the mean force), force-weighted position and normal, and mean friction. A short impact
between two samples is reported, with a force that does not depend on the time step.
Particle fluids' contacts are those of the sample's step.

Particle fluids are not on ``/tf``: each monitoring step writes one ``MarkerArray`` on the
markers topic with a ``SPHERE_LIST`` marker per fluid (namespace :data:`PARTICLES_NS`, text
= the fluid's name, points = the particles' world positions).

A step hook that reports a fluid's heat (a method ``thermal_state()`` giving a
:class:`~projection_server.simulation.batter.heat.ThermalState`) has it written every
monitoring step: the fluid's temperatures and set flags on the batter topic, and its bonds
in force on the bonds topic at the first step and whenever they change.

A task that reports its state (a method ``state() -> [(robot, step, action, target),
...]``: the index of the plan step under way or -1, the step's or the program phase's name,
the entity it acts on or ``''``) has it written every monitoring step, a ``TaskState`` per
robot; a task without that method has nothing written. Each robot whose body has a URDF
(``Body.urdf``) is described once at t = 0 on its ``robot_description`` topic, its links
renamed to their ``/tf`` frames, so that RViz and Foxglove draw it.
"""

from __future__ import annotations

import copy
import functools
import math
from pathlib import Path
from typing import Any, TYPE_CHECKING
import xml.etree.ElementTree as ET

import numpy as np

from projection_server.bags import (CdrTemplate, PARTICLES_NS, Record,
                                    robot_description_topic, TfBlock, TOPICS, typestore)
from projection_server.simulation.physics import ContactSample, Shape

if TYPE_CHECKING:
    from projection_server.bags import BagWriter
    from projection_server.simulation.physics import Body, Physics

__all__ = ['ContactAggregator', 'Monitor', 'WORLD_FRAME', 'robot_description']

WORLD_FRAME = 'world'
FLUSH_SAMPLES = 256   # samples held at most before they are written (:meth:`Monitor.flush`)
_MSG = 'projection_interfaces/msg/'


class Monitor:
    """Writes what a projection's timeline is made from, at the monitoring rate, and keeps
    it as :class:`Record` s in :attr:`records`.

    The messages of every sample are serialized by :class:`~projection_server.bags.
    CdrTemplate` s of their layout (kept per process), from the numbers of the sample.
    """

    def __init__(self, physics: Physics, bag: BagWriter, task: Any = None):
        """``task``: the projection's task; its ``state()``, if it has one, is logged."""
        self.physics = physics
        self.bag = bag
        self._task_state = getattr(task, 'state', None)
        self._records: list[Record] = []
        self._pending: list[tuple[int, list[Any]]] = []   # samples not written yet
        self.contacts = ContactAggregator(physics)
        physics.step_hooks.append(self.contacts.add_step)
        # The robot's links hang off their URDF parents (a tf chain under the robot);
        # other multibodies' links, like their bases, off the world.
        self._parents = {body.name: _link_parents(physics, body)
                         for body in physics.bodies.values() if body.driven}
        self._frames: list[tuple[Any, ...]] | None = None
        self._tf: tuple[tuple[str, str], ...] = ()
        self._tf_template: CdrTemplate | None = None
        self._recorder: Any = None   # the frames' poses: Physics.frame_recorder
        self._clock_pack = _clock_template().pack
        self._grippers: dict[tuple[Any, str], tuple[Any, tuple[str, str, list[str]]]] = {}
        self._objects: tuple[tuple[str, ...] | None, Any] = (None, None)   # names, their pack
        self._thermal = [hook.thermal_state for hook in physics.step_hooks
                         if hasattr(hook, 'thermal_state')]
        self._bonds: dict[str, Any] = {}   # fluid -> the bonds last logged

    def start(self, info: dict[str, str]) -> None:
        """t = 0: the projection's description, the static poses and the shapes."""
        bag = self.bag
        message = bag.new(_MSG + 'ProjectionInfo', header=_header(0), **info)
        bag.write(TOPICS['info'], message, 0)
        self._records.append(Record('info', 0, message))
        static = [(WORLD_FRAME, b.name, *self.physics.pose(b.name))
                  for b in self.physics.bodies.values() if b.static]
        bag.write(TOPICS['tf_static'], bag.new('tf2_msgs/msg/TFMessage', transforms=[
            _transform(0, *frame) for frame in static]), 0)
        self._records.append(Record('tf_static', 0, static))
        robots = [b for b in self.physics.bodies.values() if b.driven and b.urdf is not None]
        for index, body in enumerate(robots):
            bag.write(robot_description_topic(body.name, index), bag.new(
                'std_msgs/msg/String', data=robot_description(body.name, body.urdf)), 0)
        self._markers(0)
        if self.physics.fluids:
            self.bag.write_sample(0, [self._particles(0, 0, 0)])

    @property
    def records(self) -> list[Record]:
        """What the monitor has logged so far (reading them first writes the samples still
        held: :meth:`flush`)."""
        self.flush()
        return self._records

    def sample(self) -> None:
        """One monitoring step: poses, contacts, grippers and object states.

        The sample's poses are read now and its messages made but for ``/tf``; its
        ``/tf`` messages are made, and its messages written, for many samples at once
        (:meth:`flush`)."""
        physics, records = self.physics, self._records
        t = physics.time_ns
        sec, nanosec = divmod(t, 1_000_000_000)
        if physics.shapes_changed:
            self.flush()
            self._markers(t)
            self._frames = None
        if self._frames is None:
            self.flush()
            self._plan()
        self._recorder.add()
        messages: list[Any] = [None, (TOPICS['clock'], 'rosgraph_msgs/msg/Clock',
                                      self._clock_pack((sec, nanosec)))]
        if physics.fluids:
            messages.append(self._particles(t, sec, nanosec))
        contacts = self.contacts.take()
        values = [sec, nanosec]
        for _, numbers in contacts:
            values += numbers
        template = _contacts_template(tuple(pair for pair, _ in contacts))
        messages.append((TOPICS['contacts'], template.msgtype, template.pack(values)))
        records.append(Record('contacts', t, [(*pair, numbers[6], tuple(map(float, numbers[3:6])))
                                              for pair, numbers in contacts]))
        for gripper in physics.grippers.values():
            command = gripper.command
            layout = self._grippers.get((gripper, command))
            if layout is None:   # a gripper's layout of each command, made once
                fingers = tuple(gripper.finger_links)
                layout = self._grippers[(gripper, command)] = (
                    _gripper_template(gripper.name, command, fingers).pack,
                    (gripper.name, command, list(fingers)))
            opening, measured_force = gripper.state()
            messages.append((TOPICS['gripper'], _MSG + 'GripperState', layout[0]((
                sec, nanosec, opening, gripper.commanded_force, measured_force))))
            records.append(Record('gripper', t, layout[1]))
        states = [(model.name, *model.sample()) for model in physics.models]
        values = [sec, nanosec]
        for _, load, limit, broken in states:
            values += (load, limit, broken)
        names = tuple(state[0] for state in states)
        if names != self._objects[0]:
            self._objects = names, _objects_template(names).pack
        messages.append((TOPICS['objects'], _MSG + 'ObjectStateArray',
                         self._objects[1](values)))
        records.append(Record('objects', t, states))
        for thermal_state in self._thermal:
            messages += self._batter(t, thermal_state())
        if self._task_state is not None:
            for robot, step, action, target in self._task_state():
                state = (str(robot), int(step), str(action), str(target))
                messages.append((TOPICS['task'], _MSG + 'TaskState',
                                 _task_template(state).pack((sec, nanosec))))
                records.append(Record('task', t, state))
        self._pending.append((t, messages))
        if len(self._pending) >= FLUSH_SAMPLES:
            self.flush()

    def flush(self) -> None:
        """Write the samples held: their ``/tf`` messages made for all of them at once
        (:meth:`~projection_server.bags.CdrTemplate.pack_rows`), then each sample's messages
        in its order, and record their poses as one ``tf_block``."""
        pending = self._pending
        if not pending:
            return
        self._pending = []
        positions, quaternions = self._recorder.take()
        n, k = positions.shape[:2]
        times = np.fromiter([t for t, _ in pending], np.int64, count=n)
        values = np.empty((n, k, 9))
        values[:, :, 0] = (times // 1_000_000_000)[:, None]
        values[:, :, 1] = (times % 1_000_000_000)[:, None]
        values[:, :, 2:5] = positions
        values[:, :, 5:] = quaternions
        template = self._tf_template
        blob, size = template.pack_rows(values.reshape(n, k * 9)), template.size
        topic, msgtype = TOPICS['tf'], template.msgtype
        for i, (_, messages) in enumerate(pending):
            messages[0] = (topic, msgtype, blob[i * size:(i + 1) * size])
        self.bag.write_samples(pending)
        self._records.append(Record('tf_block', pending[0][0],
                                    TfBlock(times, self._tf, positions, quaternions)))

    # --- the sample's parts -------------------------------------------------------------
    def _batter(self, t: int, state: Any) -> list[tuple[str, str, bytes]]:
        """A fluid's thermal state at ``t``: recorded, and its messages returned (its bonds
        only when they changed)."""
        count = len(state.temperatures)
        messages = [(TOPICS['batter'], 'std_msgs/msg/Float64MultiArray',
                     _batter_template(state.fluid, count).pack(
                         [*state.temperatures.tolist(), *state.set.astype(float).tolist()]))]
        self._records.append(Record('batter', t, {state.fluid: (state.temperatures,
                                                                state.set)}))
        last = self._bonds.get(state.fluid)
        if last is None or not np.array_equal(last, state.bonds):
            self._bonds[state.fluid] = state.bonds
            message = _new('std_msgs/msg/UInt32MultiArray', layout=_layout(
                state.fluid, len(state.bonds), 2), data=state.bonds.astype(np.uint32).ravel())
            messages.append((TOPICS['bonds'], 'std_msgs/msg/UInt32MultiArray',
                             typestore().serialize_cdr(message, 'std_msgs/msg/UInt32MultiArray')))
            self._records.append(Record('bonds', t, {state.fluid: state.bonds}))
        return messages

    def _plan(self) -> None:
        """The frames on ``/tf``: the moving bodies and their links, a robot's links
        relative to their parent links (the frames' order of ``self._tf``)."""
        frames, tf = [], []
        for body in self.physics.bodies.values():
            if body.static or body.group is not None:
                continue
            tf.append((WORLD_FRAME, body.name))
            parents = self._parents.get(body.name)
            if parents is None:
                links = list(body.links)
                tf += [(WORLD_FRAME, f'{body.name}/{body.links[link]}') for link in links]
                frames.append((body.body_id, links, None))
                continue
            chain = [(link, parents[link]) for link in sorted(body.links)]  # parents first
            tf += [(_link_frame(body, parent), _link_frame(body, link))
                   for link, parent in chain]
            frames.append((body.body_id, [link for link, _ in chain], chain))
        self._frames, self._tf = frames, tuple(tf)
        self._tf_template = _tf_template(self._tf)
        self._recorder = self.physics.frame_recorder(frames)

    def _markers(self, t: int) -> None:
        layout = []   # (frame, shape, offset) of each marker
        for body in self.physics.bodies.values():
            if body.shape is not None:
                layout.append((body.name, body.shape, (0.0, 0.0, 0.0)))
            for link, shapes in body.link_shapes.items():
                for shape, offset in shapes:
                    layout.append((_link_frame(body, link), shape, tuple(map(float, offset))))
        self.physics.shapes_changed = False
        template = _markers_template(tuple(layout))
        sec, nanosec = divmod(t, 1_000_000_000)
        self.bag.write_sample(t, [(TOPICS['markers'], template.msgtype,
                                   template.pack((sec, nanosec) * (2 * len(layout))))])

    def _particles(self, t: int, sec: int, nanosec: int) -> tuple[str, str, bytes]:
        """The fluids' particles at ``t``: recorded, and their message returned."""
        fluids = tuple(self.physics.fluids.values())
        positions = {fluid.name: self.physics.particle_positions(fluid.name)
                     for fluid in fluids}
        values: list[Any] = []
        for fluid in fluids:
            values += (sec, nanosec, *positions[fluid.name].ravel().tolist(), sec, nanosec)
        template = _particles_template(tuple(
            (fluid.name, fluid.radius, fluid.color, len(positions[fluid.name]))
            for fluid in fluids))
        self._records.append(Record('particles', t, positions))
        return TOPICS['markers'], template.msgtype, template.pack(values)


# --- message layouts (per process) and parts -----------------------------------------------
# Each template is made once per layout and process: a worker's projections of one scenario
# share their frames, gripper states and most contact sets.

def _template(msgtype: str, prototype: Any, variable: tuple[str, ...]) -> CdrTemplate:
    return CdrTemplate(typestore(), msgtype, prototype, variable)


def _new(msgtype: str, **fields: Any) -> Any:
    return typestore().types[msgtype](**fields)


@functools.cache
def _clock_template() -> CdrTemplate:
    return _template('rosgraph_msgs/msg/Clock',
                     _new('rosgraph_msgs/msg/Clock', clock=_stamp(0)), ('clock.*',))


@functools.lru_cache(maxsize=64)
def _tf_template(frames: tuple[tuple[str, str], ...]) -> CdrTemplate:
    transforms = [_transform(0, parent, child, (0.0,) * 3, (0.0, 0.0, 0.0, 1.0))
                  for parent, child in frames]
    return _template('tf2_msgs/msg/TFMessage',
                     _new('tf2_msgs/msg/TFMessage', transforms=transforms),
                     ('transforms.*.header.stamp.*', 'transforms.*.transform.*'))


@functools.lru_cache(maxsize=1024)
def _contacts_template(pairs: tuple[tuple[str, str, str, str], ...]) -> CdrTemplate:
    zero = (0.0, 0.0, 0.0)
    contacts = [_new(_MSG + 'Contact', body_a=a, link_a=la, body_b=b, link_b=lb,
                     position=_point(zero), normal=_vector(zero), normal_force=0.0,
                     friction_force=_vector(zero))
                for a, la, b, lb in pairs]
    return _template(_MSG + 'ContactArray',
                     _new(_MSG + 'ContactArray', header=_header(0), contacts=contacts),
                     ('header.stamp.*', 'contacts.*'))


@functools.lru_cache(maxsize=64)
def _gripper_template(name: str, command: str, fingers: tuple[str, ...]) -> CdrTemplate:
    return _template(_MSG + 'GripperState', _new(
        _MSG + 'GripperState', header=_header(0), name=name, command=command,
        opening=0.0, commanded_force=0.0, measured_force=0.0, finger_links=list(fingers)),
        ('header.stamp.*', 'opening', 'commanded_force', 'measured_force'))


@functools.lru_cache(maxsize=64)
def _objects_template(names: tuple[str, ...]) -> CdrTemplate:
    states = [_new(_MSG + 'ObjectState', name=name, load=0.0, load_limit=0.0, broken=False)
              for name in names]
    return _template(_MSG + 'ObjectStateArray', _new(
        _MSG + 'ObjectStateArray', header=_header(0), objects=states),
        ('header.stamp.*', 'objects.*'))


@functools.lru_cache(maxsize=256)
def _task_template(state: tuple[str, int, str, str]) -> CdrTemplate:
    """A ``TaskState`` of ``(robot, step, action, target)``: a task has a few states."""
    robot, step, action, target = state
    return _template(_MSG + 'TaskState', _new(
        _MSG + 'TaskState', header=_header(0), robot=robot, step=step, action=action,
        target=target), ('header.stamp.*',))


@functools.lru_cache(maxsize=16)
def _batter_template(fluid: str, count: int) -> CdrTemplate:
    """A ``Float64MultiArray`` of a fluid's ``count`` temperatures, then its set flags."""
    return _template('std_msgs/msg/Float64MultiArray', _new(
        'std_msgs/msg/Float64MultiArray', layout=_layout(fluid, 2, count),
        data=np.zeros(2 * count)), ('data.*',))


def _layout(label: str, rows: int, columns: int) -> Any:
    """A two-dimensional ``MultiArrayLayout``: ``rows`` labelled ``label``, each of
    ``columns``."""
    dim = 'std_msgs/msg/MultiArrayDimension'
    return _new('std_msgs/msg/MultiArrayLayout', dim=[
        _new(dim, label=label, size=rows, stride=rows * columns),
        _new(dim, label='', size=columns, stride=columns)], data_offset=0)


@functools.lru_cache(maxsize=64)
def _markers_template(layout: tuple[tuple[str, Shape, tuple[float, float, float]], ...]
                      ) -> CdrTemplate:
    """A ``MarkerArray`` of the bodies' shapes, a marker per ``(frame, shape, offset)``;
    its stamps (each marker's and its texture's) vary."""
    markers = [_marker(0, index, frame, shape, offset)
               for index, (frame, shape, offset) in enumerate(layout)]
    return _template('visualization_msgs/msg/MarkerArray',
                     _new('visualization_msgs/msg/MarkerArray', markers=markers),
                     ('markers.*.header.stamp.*', 'markers.*.texture.header.stamp.*'))


@functools.lru_cache(maxsize=16)
def _particles_template(fluids: tuple[tuple[str, float, tuple[float, ...], int], ...]
                        ) -> CdrTemplate:
    """A ``MarkerArray`` of a ``SPHERE_LIST`` marker per fluid (name, radius, colour,
    number of particles)."""
    markers = []
    for index, (name, radius, color, count) in enumerate(fluids):
        marker = _marker(0, index, WORLD_FRAME,
                         Shape('sphere', (2 * radius,) * 3, color), (0.0, 0.0, 0.0))
        marker.ns, marker.type, marker.text = PARTICLES_NS, marker.SPHERE_LIST, name
        marker.frame_locked = False
        marker.points = [_point((0.0, 0.0, 0.0)) for _ in range(count)]
        markers.append(marker)
    return _template('visualization_msgs/msg/MarkerArray',
                     _new('visualization_msgs/msg/MarkerArray', markers=markers),
                     ('markers.*.header.stamp.*', 'markers.*.points.*',
                      'markers.*.texture.header.stamp.*'))


def _marker(t: int, index: int, frame: str, shape: Shape, offset: Any) -> Any:
    marker = typestore().types['visualization_msgs/msg/Marker']
    kinds = {'box': marker.CUBE, 'cylinder': marker.CYLINDER, 'sphere': marker.SPHERE}
    empty = np.zeros(0, dtype=np.uint8)
    return marker(
        header=_header(t, frame), ns='bodies', id=index, type=kinds[shape.kind],
        action=marker.ADD, pose=_new('geometry_msgs/msg/Pose', position=_point(offset),
                                     orientation=_new('geometry_msgs/msg/Quaternion', **dict(
                                         zip('xyzw', map(float, shape.orientation))))),
        scale=_vector(shape.size),
        color=_new('std_msgs/msg/ColorRGBA', r=shape.color[0], g=shape.color[1],
                   b=shape.color[2], a=shape.color[3]),
        lifetime=_new('builtin_interfaces/msg/Duration', sec=0, nanosec=0),
        frame_locked=True, points=[], colors=[], texture_resource='',
        texture=_new('sensor_msgs/msg/CompressedImage', header=_header(t),
                     format='', data=empty),
        uv_coordinates=[], text=frame, mesh_resource='',
        mesh_file=_new('visualization_msgs/msg/MeshFile', filename='', data=empty),
        mesh_use_embedded_materials=False)


def _stamp(t: int) -> Any:
    return _new('builtin_interfaces/msg/Time', sec=t // 1_000_000_000,
                nanosec=t % 1_000_000_000)


def _header(t: int, frame: str = WORLD_FRAME) -> Any:
    return _new('std_msgs/msg/Header', stamp=_stamp(t), frame_id=frame)


def _point(xyz: Any) -> Any:
    return _new('geometry_msgs/msg/Point', x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))


def _vector(xyz: Any) -> Any:
    return _new('geometry_msgs/msg/Vector3', x=float(xyz[0]), y=float(xyz[1]),
                z=float(xyz[2]))


def _transform(t: int, parent: str, child: str, position: Any,
               orientation: Any) -> Any:
    return _new('geometry_msgs/msg/TransformStamped', header=_header(t, parent),
                child_frame_id=child, transform=_new(
                    'geometry_msgs/msg/Transform', translation=_vector(position),
                    rotation=_new('geometry_msgs/msg/Quaternion', x=orientation[0],
                                  y=orientation[1], z=orientation[2], w=orientation[3])))


class ContactAggregator:
    """The contacts of every physics step since the last :meth:`take`, per link pair."""

    def __init__(self, physics: Physics):
        self.physics = physics
        self._steps = 0
        # key -> [sum f, sum f*x, y, z, sum f*n x, y, z, sum friction x, y, z, points,
        #         sum x, y, z, sum n x, y, z]
        self._sums: dict[tuple[str, str, str, str], list[float]] = {}
        self._version = -1   # of the physics' bodies that _bodies and _pairs are of
        self._bodies: list[int] = []
        self._pairs: dict[tuple[int, int, int, int], Any] = {}
        self._particles: set[int] = set()
        self._skipped: dict[int, set[int]] = {}

    def add_step(self) -> None:
        """Add the contacts of the step just made."""
        self._steps += 1
        if self._version != self.physics.bodies_version:
            self._replan()
        pairs, sums, bodies, skipped = self._pairs, self._sums, self._bodies, self._skipped
        for body, points in zip(bodies, self.physics.contact_points_of(bodies)):
            skip = skipped[body]
            for point in points:
                # Most of a pour's points (particles), and those counted from the other body.
                if point[2] in skip:
                    continue
                pair_key = (body, point[3], point[2], point[4])
                pair = pairs.get(pair_key, False)
                if pair is False:
                    pair = pairs[pair_key] = self._pair(*pair_key)
                if pair is None:
                    continue
                key, sign, turned = pair
                (_, _, _, _, _, (xa, ya, za), (xb, yb, zb), (nx, ny, nz), _, f,
                 f1, (d1x, d1y, d1z), f2, (d2x, d2y, d2z)) = point
                x, y, z = (xa + xb) / 2, (ya + yb) / 2, (za + zb) / 2
                if turned:
                    # Asked from the later of a pair's bodies, PyBullet turns the normal round
                    # but not the friction directions.
                    f1, f2 = -f1, -f2
                row = sums.get(key)
                if row is None:
                    row = sums[key] = [0.0] * 17
                # Force-weighted sums are all a sample needs once a point carries force
                # (Bullet's normal forces are not negative), plain sums otherwise (those of
                # all its points, none of which carries any). A point without force is
                # left out of the weighted ones: it would add 0, or -0.
                if f != 0.0:
                    row[0] += f
                    row[1] += f * x
                    row[2] += f * y
                    row[3] += f * z
                    row[4] += f * (sign * nx)
                    row[5] += f * (sign * ny)
                    row[6] += f * (sign * nz)
                row[7] += sign * (f1 * d1x + f2 * d2x)
                row[8] += sign * (f1 * d1y + f2 * d2y)
                row[9] += sign * (f1 * d1z + f2 * d2z)
                if not f > 0.0:
                    row[10] += 1
                    row[11] += x
                    row[12] += y
                    row[13] += z
                    row[14] += sign * nx
                    row[15] += sign * ny
                    row[16] += sign * nz

    def _replan(self) -> None:
        """The bodies to ask for contacts (of the world as it is now), once per change."""
        physics = self.physics
        self._bodies = [b.body_id for b in physics.bodies.values()
                        if not b.static and b.group is None]
        self._pairs = {}
        self._particles = {b for fluid in physics.fluids.values() for b in fluid.body_ids}
        # Per body, the bodies whose contacts with it are not counted from it.
        self._skipped = {body: self._particles | {other for other in self._bodies
                                                  if other < body}
                         for body in self._bodies}
        self._version = physics.bodies_version

    def _pair(self, body: int, link: int, other: int, other_link: int
              ) -> tuple[tuple[str, str, str, str], float, bool] | None:
        """``(key, sign, turned)`` of the contacts of ``body``'s ``link`` with ``other``'s
        ``other_link`` asked from ``body``; None if they are not counted from it."""
        physics = self.physics
        if other < body and other in self._bodies:
            return None   # counted from the other body
        a, b = physics.name_of(body), physics.name_of(other)
        if b is None or b in physics.fluids:
            return None
        key_a = (a, physics.link_name(body, link))
        key_b = (b, physics.link_name(other, other_link))
        sign = 1.0 if key_a < key_b else -1.0
        key = (*key_a, *key_b) if sign > 0 else (*key_b, *key_a)
        return key, sign, other < body

    def take(self) -> list[tuple[tuple[str, str, str, str], tuple[Any, ...]]]:
        """The aggregated contacts since the last call (and the fluids' of this step),
        sorted by link pair; starts a new period. Each is ``(link pair, numbers)``, the
        numbers of its message: position (3), normal (3), normal force, friction (3)."""
        steps = max(1, self._steps)
        out = []
        sqrt = math.sqrt
        for key, row in self._sums.items():
            total = row[0]
            if total > 0:
                x, y, z = row[1] / total, row[2] / total, row[3] / total
                nx, ny, nz = row[4], row[5], row[6]
            else:
                points = row[10]
                x, y, z = row[11] / points, row[12] / points, row[13] / points
                nx, ny, nz = row[14], row[15], row[16]
            norm = sqrt(nx * nx + ny * ny + nz * nz)   # what np.linalg.norm gives, bit for bit
            if norm > 0:
                nx, ny, nz = nx / norm, ny / norm, nz / norm
            else:
                nx, ny, nz = 0.0, 0.0, 1.0
            out.append((key, (x, y, z, nx, ny, nz, total / steps,
                              row[7] / steps, row[8] / steps, row[9] / steps)))
        if self.physics.fluids:
            fluids = self.physics.fluids
            out += [(_pair_of(c), (*c.position, *c.normal, c.normal_force, *c.friction))
                    for c in self.physics.contacts()
                    if c.body_a in fluids or c.body_b in fluids]
        self._sums = {}
        self._steps = 0
        out.sort(key=_first)
        return out


def _pair_of(contact: ContactSample) -> tuple[str, str, str, str]:
    return contact.body_a, contact.link_a, contact.body_b, contact.link_b


def _first(item: tuple[Any, ...]) -> Any:
    return item[0]


def _link_frame(body: Body, link: int) -> str:
    return f'{body.name}/{body.links[link]}' if link >= 0 else body.name


def _link_parents(physics: Physics, body: Body) -> dict[int, int]:
    """Link index -> index of its parent link (-1: the base), from the loaded URDF."""
    return {link: physics.link_parent(body.body_id, link) for link in body.links}


@functools.lru_cache(maxsize=16)
def robot_description(robot: str, urdf: str) -> str:
    """The URDF at path ``urdf`` of robot ``robot``, its links named as their ``/tf``
    frames: the root link ``robot``, every other link L ``robot/L``. A link without visuals
    shows its collision shapes (what the simulation has of it); relative mesh files become
    absolute ``file://`` URIs."""
    path = Path(urdf)
    root = ET.parse(path).getroot()
    children = {child.get('link') for child in root.iter('child')}
    links = [link.get('name') for link in root.findall('link')]
    frames = {name: robot if name not in children else f'{robot}/{name}' for name in links}
    for link in root.findall('link'):
        link.set('name', frames[link.get('name')])
        if link.find('visual') is None:
            for collision in link.findall('collision'):
                visual = ET.SubElement(link, 'visual')
                visual.extend(copy.deepcopy(element) for element in collision)
    for joint in root.findall('joint'):
        for end in ('parent', 'child'):
            element = joint.find(end)
            if element is not None and element.get('link') in frames:
                element.set('link', frames[element.get('link')])
    for mesh in root.iter('mesh'):
        filename = mesh.get('filename', '')
        if filename and '://' not in filename:
            mesh.set('filename', (path.parent / filename).resolve().as_uri())
    return ET.tostring(root, encoding='unicode')


def _relative(physics: Physics, parent: Any, child: Any) -> tuple[Any, Any]:
    """The pose ``child`` (world) in the frame of the pose ``parent`` (world)."""
    return physics.multiply_transforms(*physics.invert_transform(*parent), *child)
