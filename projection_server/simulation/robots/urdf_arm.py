"""``urdf``: any robot arm given as a URDF plus the facts a plan needs of it.

The robot entity's properties:

* ``file``: the URDF (resolved in the asset directories), loaded with its base fixed at the
  entity's pose (the base frame of the URDF);
* ``tool_link`` and ``tool_offset``: the link that carries the tool point and the point's
  offset in that link's frame, midway between the finger pads; the tool frame is the link's
  frame (its z axis should be the direction the fingers point, y the one they close along:
  :mod:`.manipulator`'s conventions);
* ``finger_joints``: the prismatic joints of the fingers, each of whose value is its pad's
  distance from the tool point (0: closed). Fingers coupled in the URDF (a ``mimic``
  joint) are coupled in the simulation too (a gear constraint), so the gripper is one
  drive that centres what it grasps;
* ``max_force``: the grip force limit [N] (each finger pushes with at most the commanded
  force, and at most this);
* ``home``: the arm joints' values at the start (default: the middle of each joint's
  range).

The links' friction coefficient is :data:`FRICTION` (rubber pads), as the PR2 gripper's.

Every other non-fixed joint is an arm joint, moved by position control with the URDF's
effort limit; the plan's tool poses are solved by :mod:`.kinematics`.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, TYPE_CHECKING
import xml.etree.ElementTree as ET

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.physics import Body, Gripper
from projection_server.simulation.robots.manipulator import Arm
from projection_server.simulation.robots.registry import register, RobotModel

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['PROPERTIES', 'URDF_ARM']

PROPERTIES = ('file', 'tool_link', 'tool_offset', 'finger_joints', 'max_force', 'home')
REQUIRED = ('file', 'tool_link', 'tool_offset', 'finger_joints', 'max_force')
TRACKING_RATE = 24.0   # 1/s, as the gantry's (robots.gantry)
COUPLING_FORCE = 100.0   # N of the gear that couples mimic fingers
FRICTION = 1.0           # of every link: the fingers' pads are rubber


def build(physics: Physics, entity: Entity, gripper: Entity | None = None) -> None:
    c, p = physics.client, entity.properties
    if not physics.tool_control:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: a URDF arm is driven by plans only (the named '
                              'programs drive the PR2 gripper); give a plan([...])')
    urdf = p['file']
    orientation = c.getQuaternionFromEuler(entity.pose.rpy)
    body_id = c.loadURDF(urdf, entity.pose.xyz, orientation, useFixedBase=True,
                         flags=c.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT)
    if body_id < 0:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'{entity.name}: cannot load {urdf}')
    joints, links, kinds = {}, {}, {}
    for j in range(c.getNumJoints(body_id)):
        info = c.getJointInfo(body_id, j)
        joints[info[1].decode()] = j
        links[j] = info[12].decode()
        kinds[j] = info[2]
    link_index = {name: j for j, name in links.items()}
    missing = [n for n in p['finger_joints'] if n not in joints]
    if p['tool_link'] not in link_index or missing:
        unknown = missing or [p['tool_link']]
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: {Path(urdf).name} has no '
                              f'{"joint" if missing else "link"} {", ".join(unknown)}')
    fingers = [joints[n] for n in p['finger_joints']]
    arm = [j for j in sorted(kinds) if kinds[j] != c.JOINT_FIXED and j not in fingers]
    home = p.get('home')
    if home is not None and len(home) != len(arm):
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: home has {len(home)} values, the arm has '
                              f'{len(arm)} joints')
    if home is None:
        home = [_middle(c.getJointInfo(body_id, j)) for j in arm]
    for link in range(-1, c.getNumJoints(body_id)):
        c.changeDynamics(body_id, link, lateralFriction=FRICTION)
    for joint, value in zip(arm, home):
        c.resetJointState(body_id, joint, value)
    opening = sum(c.getJointInfo(body_id, j)[9] for j in fingers)
    for finger in fingers:
        c.resetJointState(body_id, finger, c.getJointInfo(body_id, finger)[9])
    for child, parent in _mimics(urdf).items():
        if child in joints and parent in joints:
            _couple(c, body_id, joints[parent], joints[child])
    physics.add_body(Body(entity.name, entity.cls, body_id, False, None, links=links,
                          driven=True, urdf=urdf))
    gain = min(1.0, TRACKING_RATE / physics.settings.physics.rate_hz)
    hand = Gripper(c, entity.name, body_id, {'fingers': fingers}, [],
                   max_joint_force=max(c.getJointInfo(body_id, j)[10] for j in fingers),
                   max_force=p['max_force'], max_opening=opening, position_gain=gain,
                   finger_links=[links[j] for j in fingers])
    hand.open(opening, speed=0.1)
    physics.grippers[entity.name] = hand
    manipulator = Arm(c, entity.name, body_id, urdf, 1.0, (entity.pose.xyz, orientation), arm,
                      link_index[p['tool_link']], p['tool_offset'], hand, gain)
    manipulator.servo(*manipulator.tool_pose())
    physics.manipulators[entity.name] = manipulator


def check(name: str, properties: dict[str, Any]) -> None:
    """The URDF arm's facts are all given."""
    missing = [key for key in REQUIRED if key not in properties]
    if missing:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{name}: a urdf robot needs {", ".join(missing)}')


def _middle(info: Any) -> float:
    lower, upper = info[8], info[9]
    return 0.0 if upper < lower else (lower + upper) / 2   # continuous joints: 0


def _couple(client: Any, body_id: int, parent: int, child: int) -> None:
    """Fingers that move as one: a gear of ratio -1 between the two joints (their values
    stay equal, the joints' axes being opposite)."""
    gear = client.createConstraint(body_id, parent, body_id, child, client.JOINT_GEAR,
                                   (1, 0, 0), (0, 0, 0), (0, 0, 0))
    client.changeConstraint(gear, gearRatio=-1, maxForce=COUPLING_FORCE, erp=0.2)


@functools.cache
def _mimics(urdf: str) -> dict[str, str]:
    """The URDF's mimic joints: child joint name -> the joint it follows."""
    try:
        root = ET.parse(urdf).getroot()
    except (OSError, ET.ParseError):
        return {}
    return {joint.get('name'): mimic.get('joint') for joint in root.iter('joint')
            for mimic in joint.iter('mimic')}


URDF_ARM = register(RobotModel('urdf', build, doc=__doc__.splitlines()[0],
                               properties=PROPERTIES, check=check))
