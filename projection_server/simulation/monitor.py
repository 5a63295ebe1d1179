"""Monitoring: turns the state of a :class:`Physics` into bag messages (topics: ``bags``).

Particle fluids are not on ``/tf``: each monitoring step writes one ``MarkerArray`` on the
markers topic with a ``SPHERE_LIST`` marker per fluid (namespace :data:`PARTICLES_NS`, text
= the fluid's name, points = the particles' world positions).
"""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.bags import TOPICS
from projection_server.simulation.physics import Shape

if TYPE_CHECKING:
    from projection_server.bags import BagWriter
    from projection_server.simulation.physics import Body, Physics

__all__ = ['Monitor', 'PARTICLES_NS', 'WORLD_FRAME']

WORLD_FRAME = 'world'
PARTICLES_NS = 'particles'
_MSG = 'projection_interfaces/msg/'


class Monitor:
    """Writes what a projection's timeline is made from, at the monitoring rate."""

    def __init__(self, physics: Physics, bag: BagWriter):
        self.physics = physics
        self.bag = bag

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
            transforms.append(self._transform(t, body.name, *physics.pose(body.name)))
            for link, link_name in body.links.items():
                transforms.append(self._transform(t, f'{body.name}/{link_name}',
                                                  *physics.link_pose(body.name, link)))
        bag.write(TOPICS['tf'], bag.new('tf2_msgs/msg/TFMessage', transforms=transforms), t)
        self._particles(t)
        contacts = [bag.new(
            _MSG + 'Contact', body_a=c.body_a, link_a=c.link_a, body_b=c.body_b,
            link_b=c.link_b, position=self._point(c.position), normal=self._vector(c.normal),
            normal_force=c.normal_force, friction_force=self._vector(c.friction))
            for c in physics.contacts()]
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

    def _header(self, t: int, frame: str = WORLD_FRAME) -> Any:
        stamp = self.bag.new('builtin_interfaces/msg/Time', sec=t // 1_000_000_000,
                             nanosec=t % 1_000_000_000)
        return self.bag.new('std_msgs/msg/Header', stamp=stamp, frame_id=frame)

    def _point(self, xyz: Any) -> Any:
        return self.bag.new('geometry_msgs/msg/Point', x=float(xyz[0]), y=float(xyz[1]),
                            z=float(xyz[2]))

    def _vector(self, xyz: Any) -> Any:
        return self.bag.new('geometry_msgs/msg/Vector3', x=float(xyz[0]), y=float(xyz[1]),
                            z=float(xyz[2]))

    def _transform(self, t: int, child: str, position: Any, orientation: Any) -> Any:
        new = self.bag.new
        return new('geometry_msgs/msg/TransformStamped', header=self._header(t),
                   child_frame_id=child, transform=new(
                       'geometry_msgs/msg/Transform', translation=self._vector(position),
                       rotation=new('geometry_msgs/msg/Quaternion', x=orientation[0],
                                    y=orientation[1], z=orientation[2], w=orientation[3])))


def _link_frame(body: Body, link: int) -> str:
    return f'{body.name}/{body.links[link]}' if link >= 0 else body.name
