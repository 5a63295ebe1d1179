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
"""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.bags import TOPICS
from projection_server.simulation.physics import ContactSample, Shape

if TYPE_CHECKING:
    from projection_server.bags import BagWriter
    from projection_server.simulation.physics import Body, Physics

__all__ = ['ContactAggregator', 'Monitor', 'PARTICLES_NS', 'WORLD_FRAME']

WORLD_FRAME = 'world'
PARTICLES_NS = 'particles'
_MSG = 'projection_interfaces/msg/'


class Monitor:
    """Writes what a projection's timeline is made from, at the monitoring rate."""

    def __init__(self, physics: Physics, bag: BagWriter):
        self.physics = physics
        self.bag = bag
        self.contacts = ContactAggregator(physics)
        physics.step_hooks.append(self.contacts.add_step)
        # The robot's links hang off their URDF parents (a tf chain under the robot);
        # other multibodies' links, like their bases, off the world.
        self._parents = {body.name: _link_parents(physics, body)
                         for body in physics.bodies.values() if body.cls == 'robot'}

    def start(self, info: dict[str, str]) -> None:
        """t = 0: the projection's description, the static poses and the shapes."""
        self.bag.write(TOPICS['info'], self.bag.new(
            _MSG + 'ProjectionInfo', header=self._header(0), **info), 0)
        static = [self._transform(0, b.name, *self.physics.pose(b.name))
                  for b in self.physics.bodies.values() if b.static]
        self.bag.write(TOPICS['tf_static'],
                       self.bag.new('tf2_msgs/msg/TFMessage', transforms=static), 0)
        self._markers(0)
        self._particles(0)

    def sample(self) -> None:
        """One monitoring step: poses, contacts, grippers and object states."""
        physics, bag = self.physics, self.bag
        t = physics.time_ns
        if physics.shapes_changed:
            self._markers(t)
        transforms = []
        for body in physics.bodies.values():
            if body.static or body.group is not None:
                continue
            base = physics.pose(body.name)
            transforms.append(self._transform(t, body.name, *base))
            parents = self._parents.get(body.name)
            if parents is None:
                for link, link_name in body.links.items():
                    transforms.append(self._transform(t, f'{body.name}/{link_name}',
                                                      *physics.link_pose(body.name, link)))
                continue
            world = {-1: base}
            for link in sorted(body.links):   # PyBullet numbers a parent before its child
                world[link] = physics.link_pose(body.name, link)
                parent = parents[link]
                transforms.append(self._transform(
                    t, _link_frame(body, link), *_relative(physics, world[parent], world[link]),
                    parent=_link_frame(body, parent)))
        bag.write(TOPICS['tf'], bag.new('tf2_msgs/msg/TFMessage', transforms=transforms), t)
        bag.write(TOPICS['clock'], bag.new('rosgraph_msgs/msg/Clock', clock=self._stamp(t)), t)
        self._particles(t)
        contacts = [bag.new(
            _MSG + 'Contact', body_a=c.body_a, link_a=c.link_a, body_b=c.body_b,
            link_b=c.link_b, position=self._point(c.position), normal=self._vector(c.normal),
            normal_force=c.normal_force, friction_force=self._vector(c.friction))
            for c in self.contacts.take()]
        bag.write(TOPICS['contacts'], bag.new(_MSG + 'ContactArray', header=self._header(t),
                                              contacts=contacts), t)
        for gripper in physics.grippers.values():
            bag.write(TOPICS['gripper'], bag.new(
                _MSG + 'GripperState', header=self._header(t), name=gripper.name,
                command=gripper.command, opening=gripper.opening(),
                commanded_force=gripper.commanded_force,
                measured_force=gripper.measured_force(),
                finger_links=gripper.finger_links), t)
        states = []
        for model in physics.models:
            load, limit, broken = model.sample()
            states.append(bag.new(_MSG + 'ObjectState', name=model.name, load=load,
                                  load_limit=limit, broken=broken))
        bag.write(TOPICS['objects'], bag.new(_MSG + 'ObjectStateArray',
                                             header=self._header(t), objects=states), t)

    # --- message parts ------------------------------------------------------------------
    def _markers(self, t: int) -> None:
        markers = []
        for body in self.physics.bodies.values():
            if body.shape is not None:
                markers.append(self._marker(t, len(markers), body.name, body.shape,
                                            (0.0, 0.0, 0.0)))
            for link, shapes in body.link_shapes.items():
                for shape, offset in shapes:
                    markers.append(self._marker(t, len(markers), _link_frame(body, link),
                                                shape, offset))
        self.bag.write(TOPICS['markers'], self.bag.new(
            'visualization_msgs/msg/MarkerArray', markers=markers), t)
        self.physics.shapes_changed = False

    def _particles(self, t: int) -> None:
        if not self.physics.fluids:
            return
        markers = []
        for index, fluid in enumerate(self.physics.fluids.values()):
            points = [self._point(xyz) for xyz in self.physics.particle_positions(fluid.name)]
            marker = self._marker(t, index, WORLD_FRAME,
                                  Shape('sphere', (2 * fluid.radius,) * 3, fluid.color),
                                  (0.0, 0.0, 0.0))
            marker.ns, marker.type, marker.text = PARTICLES_NS, marker.SPHERE_LIST, fluid.name
            marker.frame_locked, marker.points = False, points
            markers.append(marker)
        self.bag.write(TOPICS['markers'], self.bag.new(
            'visualization_msgs/msg/MarkerArray', markers=markers), t)

    def _marker(self, t: int, index: int, frame: str, shape: Shape, offset: Any) -> Any:
        new = self.bag.new
        marker = self.bag.type('visualization_msgs/msg/Marker')
        kinds = {'box': marker.CUBE, 'cylinder': marker.CYLINDER, 'sphere': marker.SPHERE}
        empty = np.zeros(0, dtype=np.uint8)
        return marker(
            header=self._header(t, frame), ns='bodies', id=index, type=kinds[shape.kind],
            action=marker.ADD, pose=new('geometry_msgs/msg/Pose', position=self._point(offset),
                               orientation=new('geometry_msgs/msg/Quaternion',
                                               **dict(zip('xyzw', map(float,
                                                                      shape.orientation))))),
            scale=self._vector(shape.size),
            color=new('std_msgs/msg/ColorRGBA', r=shape.color[0], g=shape.color[1],
                      b=shape.color[2], a=shape.color[3]),
            lifetime=new('builtin_interfaces/msg/Duration', sec=0, nanosec=0),
            frame_locked=True, points=[], colors=[], texture_resource='',
            texture=new('sensor_msgs/msg/CompressedImage', header=self._header(t),
                        format='', data=empty),
            uv_coordinates=[], text=frame, mesh_resource='',
            mesh_file=new('visualization_msgs/msg/MeshFile', filename='', data=empty),
            mesh_use_embedded_materials=False)

    def _stamp(self, t: int) -> Any:
        return self.bag.new('builtin_interfaces/msg/Time', sec=t // 1_000_000_000,
                            nanosec=t % 1_000_000_000)

    def _header(self, t: int, frame: str = WORLD_FRAME) -> Any:
        return self.bag.new('std_msgs/msg/Header', stamp=self._stamp(t), frame_id=frame)

    def _point(self, xyz: Any) -> Any:
        return self.bag.new('geometry_msgs/msg/Point', x=float(xyz[0]), y=float(xyz[1]),
                            z=float(xyz[2]))

    def _vector(self, xyz: Any) -> Any:
        return self.bag.new('geometry_msgs/msg/Vector3', x=float(xyz[0]), y=float(xyz[1]),
                            z=float(xyz[2]))

    def _transform(self, t: int, child: str, position: Any, orientation: Any,
                   parent: str = WORLD_FRAME) -> Any:
        new = self.bag.new
        return new('geometry_msgs/msg/TransformStamped', header=self._header(t, parent),
                   child_frame_id=child, transform=new(
                       'geometry_msgs/msg/Transform', translation=self._vector(position),
                       rotation=new('geometry_msgs/msg/Quaternion', x=orientation[0],
                                    y=orientation[1], z=orientation[2], w=orientation[3])))


class ContactAggregator:
    """The contacts of every physics step since the last :meth:`take`, per link pair."""

    def __init__(self, physics: Physics):
        self.physics = physics
        self._steps = 0
        # key -> [sum f, sum f*x, y, z, sum f*n x, y, z, sum friction x, y, z, points,
        #         sum x, y, z, sum n x, y, z]
        self._sums: dict[tuple[str, str, str, str], list[float]] = {}

    def add_step(self) -> None:
        """Add the contacts of the step just made."""
        physics = self.physics
        self._steps += 1
        fluids = physics.fluids
        bodies = [b.body_id for b in physics.bodies.values()
                  if not b.static and b.group is None]
        queried = set(bodies)
        name_of, link_name = physics.name_of, physics.link_name
        sums = self._sums
        for body in bodies:
            a = name_of(body)
            for point in physics.client.getContactPoints(bodyA=body):
                other = point[2]
                if other in queried and other < body:
                    continue   # counted from the other body
                b = name_of(other)
                if b is None or b in fluids:
                    continue
                key_a = (a, link_name(body, point[3]))
                key_b = (b, link_name(other, point[4]))
                sign = 1.0 if key_a < key_b else -1.0
                key = (*key_a, *key_b) if sign > 0 else (*key_b, *key_a)
                f = point[9]
                (xa, ya, za), (xb, yb, zb) = point[5], point[6]
                x, y, z = (xa + xb) / 2, (ya + yb) / 2, (za + zb) / 2
                nx, ny, nz = (sign * v for v in point[7])
                f1, (d1x, d1y, d1z), f2, (d2x, d2y, d2z) = point[10:14]
                if other < body:
                    # Asked from the later of a pair's bodies, PyBullet turns the normal round
                    # but not the friction directions.
                    f1, f2 = -f1, -f2
                row = sums.get(key)
                if row is None:
                    row = sums[key] = [0.0] * 17
                row[0] += f
                row[1] += f * x
                row[2] += f * y
                row[3] += f * z
                row[4] += f * nx
                row[5] += f * ny
                row[6] += f * nz
                row[7] += sign * (f1 * d1x + f2 * d2x)
                row[8] += sign * (f1 * d1y + f2 * d2y)
                row[9] += sign * (f1 * d1z + f2 * d2z)
                row[10] += 1
                row[11] += x
                row[12] += y
                row[13] += z
                row[14] += nx
                row[15] += ny
                row[16] += nz

    def take(self) -> list[ContactSample]:
        """The aggregated contacts since the last call (and the fluids' of this step),
        sorted by link pair; starts a new period."""
        steps = max(1, self._steps)
        out = []
        for key, row in self._sums.items():
            total = row[0]
            if total > 0:
                position = (row[1] / total, row[2] / total, row[3] / total)
                normal = np.array(row[4:7])
            else:
                position = (row[11] / row[10], row[12] / row[10], row[13] / row[10])
                normal = np.array(row[14:17])
            norm = float(np.linalg.norm(normal))
            out.append(ContactSample(
                *key, position=position,
                normal=tuple(normal / norm) if norm > 0 else (0.0, 0.0, 1.0),
                normal_force=total / steps,
                friction=(row[7] / steps, row[8] / steps, row[9] / steps)))
        if self.physics.fluids:
            fluids = self.physics.fluids
            out += [c for c in self.physics.contacts()
                    if c.body_a in fluids or c.body_b in fluids]
        self._sums = {}
        self._steps = 0
        return sorted(out, key=lambda c: (c.body_a, c.link_a, c.body_b, c.link_b))


def _link_frame(body: Body, link: int) -> str:
    return f'{body.name}/{body.links[link]}' if link >= 0 else body.name


def _link_parents(physics: Physics, body: Body) -> dict[int, int]:
    """Link index -> index of its parent link (-1: the base), from the loaded URDF."""
    return {link: physics.client.getJointInfo(body.body_id, link)[16] for link in body.links}


def _relative(physics: Physics, parent: Any, child: Any) -> tuple[Any, Any]:
    """The pose ``child`` (world) in the frame of the pose ``parent`` (world)."""
    client = physics.client
    return client.multiplyTransforms(*client.invertTransform(*parent), *child)
