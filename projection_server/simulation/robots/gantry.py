"""``pr2``: the PR2's parallel-jaw gripper on a gantry (lift along z, approach along x of
its base frame), parked :data:`PARK_HEIGHT` above the robot's pose until a program places
it; for plans, free, held at the plan's tool pose by a constraint, anywhere in its reach
and turned any way (:class:`~projection_server.simulation.robots.manipulator.FloatingTool`).
No arm is simulated.

The gripper's data are a URDF and a YAML description beside it (``assets/<name>.urdf`` +
``.yaml``, ``<name>`` the robot's ``gripper`` or the stem of its gripper entity's ``urdf``):
which joints lift, approach and close the fingers, the collision box and outward normal of
each finger pad, the pads' rubber stiffness and rim radius, the gantry's force limit.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any, TYPE_CHECKING
import xml.etree.ElementTree as ET

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.physics import Body, Gripper, Pad, Shape
from projection_server.simulation.robots.manipulator import FloatingTool
from projection_server.simulation.robots.registry import assets_dir, register, RobotModel

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['PARK_HEIGHT', 'PR2', 'TRACKING_RATE']

PARK_HEIGHT = 1.0   # m above the robot's pose, out of the way until a program moves it
TRACKING_RATE = 24.0     # 1/s: position control's error correction (0.1 per step at 240 Hz)
OPEN_WIDTH = 0.07        # m between the pads of a parked six-joint gripper
DEFAULT_GRIPPER = 'pr2_gripper'   # the asset of a robot without a gripper entity


def build(physics: Physics, entity: Entity, gripper: Entity | None = None) -> None:
    """The robot's gripper on its gantry, or, for a program that moves the tool
    (``physics.tool_control``: plans), on six joints (``free_urdf`` of its description);
    ``gripper`` is the gripper's own entity, if the scenario describes it (its friction and
    asset then come from there)."""
    c = physics.client
    asset = (Path(gripper.properties['urdf']).stem if gripper is not None
             else entity.properties.get('gripper', DEFAULT_GRIPPER))
    spec = _gripper_spec(asset)
    free = physics.tool_control
    urdf = assets_dir() / spec['free_urdf' if free else 'urdf']
    x, y, z = entity.pose.xyz
    body_id = c.loadURDF(str(urdf), (x, y, z + PARK_HEIGHT), useFixedBase=not free)
    joints, links = {}, {}
    for j in range(c.getNumJoints(body_id)):
        info = c.getJointInfo(body_id, j)
        joints[info[1].decode()] = j
        links[j] = info[12].decode()
    link_index = {name: j for j, name in links.items()}
    link_index[c.getBodyInfo(body_id)[0].decode()] = -1   # the root link
    try:
        joint_map = {'fingers': [joints[n] for n in spec['joints']['fingers']]}
        if not free:
            joint_map.update(lift=joints[spec['joints']['lift']],
                             approach=joints[spec['joints']['approach']])
        boxes = _urdf_boxes(urdf)
        pads = [_pad(link_index[pad['link']], pad, boxes[pad['collision']],
                     float(spec['pad_stiffness']), float(spec['pad_rim_radius']))
                for pad in spec['pads']]
    except KeyError as exc:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'gripper asset {urdf.name}: unknown name {exc}') from exc
    link_shapes: dict[int, list[tuple[Shape, tuple[float, float, float]]]] = {}
    # The root's frame on /tf is its centre of mass: its boxes are placed relative to it.
    root_inertial = np.asarray(c.getDynamicsInfo(body_id, -1)[3])
    for box in boxes.values():
        link = link_index[box['link']]
        origin = np.asarray(box['origin']) - (root_inertial if link < 0 else 0.0)
        link_shapes.setdefault(link, []).append(
            (Shape('box', box['size'], (0.3, 0.3, 0.35, 1.0)), tuple(map(float, origin))))
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
                                 links=links, link_shapes=link_shapes, driven=True,
                                 urdf=str(urdf)))
    gain = min(1.0, TRACKING_RATE / physics.settings.physics.rate_hz)
    hand = Gripper(c, body.name, body_id, joint_map, pads, float(spec['gantry_force']),
                   position_gain=gain, **limits)
    physics.grippers[entity.name] = hand
    if free:
        _park(physics, entity, body_id, hand, spec, gain)


def _park(physics: Physics, entity: Entity, body_id: int, hand: Gripper,
          spec: dict[str, Any], gain: float) -> None:
    """The free gripper as a manipulator, parked :data:`PARK_HEIGHT` above the robot's pose,
    its fingers pointing along +x, open."""
    c = physics.client
    # The palm's fingers point along its -x: the tool frame (fingers along z) is the palm
    # frame turned a quarter turn about y; parked, the tool points along the world's +x.
    tool = ((0.0, 0.0, 0.0), c.getQuaternionFromEuler((0.0, -math.pi / 2, 0.0)))
    parked = c.multiplyTransforms((0.0, 0.0, 0.0), c.getQuaternionFromEuler(
        (0.0, math.pi / 2, 0.0)), *c.invertTransform(*tool))
    x, y, z = entity.pose.xyz
    c.resetBasePositionAndOrientation(body_id, (x, y, z + PARK_HEIGHT), parked[1])
    if math.isinf(hand.max_opening):   # no gripper entity: the fingers' own travel
        hand.max_opening = sum(c.getJointInfo(body_id, j)[9] for j in hand.fingers)
    reach = tuple(tuple(r) for r in spec['free_reach'])
    manipulator = FloatingTool(c, entity.name, body_id, hand, tool, entity.pose.xyz, reach,
                               float(spec['gantry_force']), gain)
    opening = min(hand.max_opening, OPEN_WIDTH)
    for finger in hand.fingers:
        c.resetJointState(body_id, finger, opening / 2)
    hand.open(opening, speed=0.1)
    physics.manipulators[entity.name] = manipulator


@functools.cache
def _gripper_spec(name: str) -> dict[str, Any]:
    import yaml

    path = assets_dir() / f'{name}.yaml'
    if not path.is_file():
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'unknown gripper {name!r} (no {path.name})')
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


PR2 = register(RobotModel('pr2', build, properties=('gripper',),
                          doc=' '.join(__doc__.split('\n\n')[0].split())))
