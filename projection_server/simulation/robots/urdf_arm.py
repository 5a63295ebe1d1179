"""``urdf``: any robot arm given as a URDF (or an SDF) plus the facts a plan needs of it.

The robot entity's properties:

* ``file``: the URDF, or an SDF of one model (resolved in the asset directories), loaded
  with its base fixed at the entity's pose (the frame of its base link); an SDF robot's
  description is not logged (``/robot_description`` is a URDF), its links are on ``/tf``;
* ``tool_link`` and ``tool_offset``: the link that carries the tool point and the point's
  offset in that link's frame, midway between the finger pads; the tool frame is the link's
  frame turned by ``tool_rpy`` (roll, pitch, yaw; default none): its z axis the direction
  the fingers point, y the one they close along (:mod:`.manipulator`'s conventions);
* ``finger_joints``: the joints that drive the fingers, all prismatic or all revolute.
  Prismatic: each value is its pad's distance from the tool point (0: closed; open: the
  upper limit). Revolute (:mod:`.linkage`): ``finger_open`` and ``finger_closed``, their
  values open and closed (default: their limits, the one at which the pads are further
  apart being open; limits that are no finger's range, wider than a turn, must be given);
* ``pad_links``: the links that touch what the gripper holds (default: the finger joints'
  child links, for revolute fingers the links at the ends of what they move); a revolute
  gripper's opening is the distance between their collision shapes;
* ``max_force``: the grip force limit [N] (each pad pushes with at most the commanded
  force, and at most this);
* ``home``: the arm joints' values at the start (default: the middle of each joint's
  range);
* ``joint_names`` and ``joint_positions``: values of named joints at the start, over
  ``home`` (what a snapshot of ``/joint_states`` gives, :mod:`projection_server.world`):
  arm joints start there, prismatic fingers at the opening they give, held there until the
  plan moves them (a mimic joint follows its drive); revolute fingers start open.

Joints coupled in the URDF (``mimic``) are coupled in the simulation too, by gear
constraints (``child = multiplier * parent + offset``), so one drive moves a linkage and
centres what it grasps. The arm is the non-fixed joints from the base to the tool link,
moved by position control with their effort limits (one without is an error: name a tool
link before it); the plan's tool poses are solved by :mod:`.kinematics`. Any other joint
(a passive finger tip, a wrist flange) is held where it is, at 0 or its nearer limit.

The links' friction coefficient is :data:`FRICTION` (rubber pads), as the PR2 gripper's.
A fact that does not fit the model file is an ``invalid_scenario`` error that names it.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import math
from pathlib import Path
from typing import Any, NamedTuple, TYPE_CHECKING
import xml.etree.ElementTree as ET

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.physics import Body, Gripper
from projection_server.simulation.robots.kinematics import load_robot
from projection_server.simulation.robots.linkage import (cached_opening_table, finger_values,
                                                         gap, LinkageGripper)
from projection_server.simulation.robots.manipulator import Arm
from projection_server.simulation.robots.registry import register, RobotModel

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['ArmFacts', 'JointInfo', 'LinkageFacts', 'PROPERTIES', 'URDF_ARM', 'arm_facts',
           'given_fingers', 'joint_infos', 'linkage_facts', 'mimic_joints']

PROPERTIES = ('file', 'tool_link', 'tool_offset', 'tool_rpy', 'finger_joints', 'finger_open',
              'finger_closed', 'pad_links', 'max_force', 'home', 'joint_names',
              'joint_positions')
REQUIRED = ('file', 'tool_link', 'tool_offset', 'finger_joints', 'max_force')
TRACKING_RATE = 24.0   # 1/s, as the gantry's (robots.gantry)
COUPLING_FORCE = 100.0   # N (N m) of the gear that couples mimic joints
HOLD_FORCE = 100.0       # N (N m) that holds a gripper joint that is neither finger nor mimic
FRICTION = 1.0           # of every link: the fingers' pads are rubber
MIN_STROKE = 0.005       # m the pads must move apart from closed to open


class JointInfo(NamedTuple):
    """A joint as PyBullet reads it from the model file (its index is PyBullet's; its
    ``link`` the child link's name, ``parent`` the parent link's index, -1 the base)."""

    name: str
    kind: int
    link: str
    lower: float
    upper: float
    effort: float
    parent: int


def joint_infos(client: Any, body_id: int) -> tuple[JointInfo, ...]:
    """The joints of ``body_id``, in PyBullet's order."""
    infos = []
    for j in range(client.getNumJoints(body_id)):
        info = client.getJointInfo(body_id, j)
        infos.append(JointInfo(info[1].decode(), info[2], info[12].decode(), info[8],
                               info[9], info[10], info[16]))
    return tuple(infos)


@dataclass(frozen=True)
class ArmFacts:
    """A URDF arm's facts checked against its model file (see the module doc), as every
    engine builds it: joints by PyBullet index (``joints``: name -> index)."""

    infos: tuple[JointInfo, ...]
    joints: dict[str, int]
    fingers: list[int]
    revolute: bool
    tool: int
    arm: list[int]                          # the joints from the base to the tool link
    mimic: dict[str, tuple[str, float, float]]   # the file's mimic joints, by name
    mimics: dict[int, tuple[int, float, float]]  # of them, those between its joints
    given: dict[str, float]                 # joint_names -> joint_positions
    held: dict[int, float]                  # neither arm, finger nor mimic: held there
    home: list[float]                       # the arm joints' values at the start
    start: dict[int, float]                 # prismatic fingers' values at the start


def arm_facts(entity: Entity, infos: tuple[JointInfo, ...], sdf: bool = False) -> ArmFacts:
    """The facts of the ``urdf`` robot ``entity`` whose model file has the joints
    ``infos`` (an SDF has no mimic joints); an ``invalid_scenario`` error naming a fact
    that does not fit."""
    import pybullet

    p = entity.properties
    path, file = p['file'], Path(p['file']).name
    joints = {j.name: i for i, j in enumerate(infos)}
    link_index = {j.link: i for i, j in enumerate(infos)}
    for key, names, known, what in (('tool_link', [p['tool_link']], link_index, 'link'),
                                     ('finger_joints', p['finger_joints'], joints, 'joint'),
                                     ('pad_links', p.get('pad_links', []), link_index, 'link')):
        unknown = [n for n in names if n not in known]
        if unknown:
            raise _fact(entity.name, key, f'{file} has no {what} {", ".join(unknown)}')
    fingers = [joints[n] for n in p['finger_joints']]
    revolute = _finger_kind(pybullet, entity.name, p['finger_joints'],
                            [infos[j].kind for j in fingers])
    tool = link_index[p['tool_link']]
    chain, link = [], tool
    while link >= 0:   # the joints from the base to the tool link
        chain.append(link)
        link = infos[link].parent
    arm = [j for j in sorted(chain) if infos[j].kind != pybullet.JOINT_FIXED
           and j not in fingers]
    weak = [infos[j].link for j in arm if infos[j].effort <= 0]
    if weak:
        raise _fact(entity.name, 'tool_link', f'the joint to {", ".join(weak)} on the way to '
                    f'{p["tool_link"]} has no effort limit in {file}: name a tool link before '
                    'it, its offset reaching the pads')
    mimic = mimic_joints(path)
    mimics = {} if sdf else {joints[child]: (joints[parent], multiplier, offset)
                             for child, (parent, multiplier, offset) in mimic.items()
                             if child in joints and parent in joints}
    given = dict(zip(p.get('joint_names', ()), p.get('joint_positions', ())))
    unknown = [n for n in given if n not in joints]
    if unknown:
        raise _fact(entity.name, 'joint_names', f'{file} has no joint {", ".join(unknown)}')
    held = {j: given.get(info.name, _rest(info)) for j, info in enumerate(infos)
            if info.kind != pybullet.JOINT_FIXED and j not in arm and j not in fingers
            and j not in mimics}
    home = p.get('home')
    if home is not None and len(home) != len(arm):
        raise _fact(entity.name, 'home', f'{len(home)} values, the arm has {len(arm)} joints '
                    f'({", ".join(infos[j].link for j in arm)} move)')
    if home is None:
        home = [_middle(infos[j]) for j in arm]
    home = [given.get(infos[j].name, value) for j, value in zip(arm, home)]
    start = {}
    if not revolute:
        for key in ('finger_open', 'finger_closed'):
            if key in p:
                raise _fact(entity.name, key, 'the finger joints are prismatic: open is their '
                            'upper limit, closed 0')
        for finger in fingers:   # open, or as given; a finger that mimics another follows it
            name = infos[finger].name
            parent, multiplier, offset = mimic.get(name, (None, 1.0, 0.0))
            start[finger] = (given[name] if name in given else
                             multiplier * given[parent] + offset if parent in given else
                             infos[finger].upper)
    return ArmFacts(infos, joints, fingers, revolute, tool, arm, mimic, mimics, given, held,
                    home, start)


@dataclass(frozen=True)
class LinkageFacts:
    """Revolute fingers' facts (:mod:`.linkage`): the finger joints' values open and
    closed, the pad links, the opening table, the links the drive carries and the joints'
    values open."""

    open: list[float]
    closed: list[float]
    pads: list[int]
    table: tuple[list[float], list[float]]
    carried: list[int]
    start: dict[int, float]


def linkage_facts(client: Any, body_id: int, entity: Entity, facts: ArmFacts
                  ) -> LinkageFacts:
    """The revolute fingers' facts, measured on ``body_id`` of ``client`` (the robot at its
    pose before its world runs, or a copy of it): the opening table once per process,
    robot and pose."""
    p, infos, fingers = entity.properties, facts.infos, facts.fingers
    mimics, held = facts.mimics, facts.held
    if 'finger_open' in p:
        open_values, closed_values = list(p['finger_open']), list(p['finger_closed'])
    else:
        bad = [infos[j].name for j in fingers
               if not 0 < infos[j].upper - infos[j].lower <= 2 * math.pi]
        if bad:
            raise _fact(entity.name, 'finger_open', f'give finger_open and finger_closed: the '
                        f'limits of {", ".join(bad)} in {Path(p["file"]).name} are not a '
                        "finger's range (none, or wider than a turn)")
        open_values = [infos[j].upper for j in fingers]
        closed_values = [infos[j].lower for j in fingers]
    if p.get('pad_links') is None:
        pads = _subtree(client, body_id, fingers, leaves=True)
        if len(pads) < 2:
            raise _fact(entity.name, 'pad_links', 'name the links that touch what the gripper '
                        'holds: the finger joints end in '
                        f'{", ".join(infos[j].link for j in pads)} alone')
    else:
        index = {info.link: j for j, info in enumerate(infos)}
        pads = [index[n] for n in p['pad_links']]
    if 'finger_open' not in p:   # of the two limits, open is where the pads are further apart
        ends = [gap(client, body_id, finger_values(fingers, open_values, closed_values,
                                                   mimics, held, u), pads) for u in (0.0, 1.0)]
        if ends[1] < ends[0]:
            open_values, closed_values = closed_values, open_values
    key = (p['file'], tuple(fingers), tuple(open_values), tuple(closed_values),
           tuple(sorted(mimics.items())), tuple(sorted(held.items())), tuple(pads),
           tuple(entity.pose.xyz), tuple(entity.pose.rpy))
    table = cached_opening_table(key, client, body_id, fingers, open_values, closed_values,
                                 mimics, held, pads)
    if table[1][-1] - table[1][0] < MIN_STROKE:
        raise _fact(entity.name, 'finger_open', 'the pads '
                    f'{", ".join(infos[j].link for j in pads)} are '
                    f'{table[1][0] * 1000:.1f} mm apart closed and '
                    f'{table[1][-1] * 1000:.1f} mm open: give the finger joints\' values '
                    'that open and close the gripper (finger_open, finger_closed), and the '
                    'links that touch what it holds (pad_links)')
    carried = _subtree(client, body_id, [*fingers, *mimics])
    return LinkageFacts(open_values, closed_values, pads, table, carried,
                        finger_values(fingers, open_values, closed_values, mimics, held, 1.0))


def build(physics: Physics, entity: Entity, gripper: Entity | None = None) -> None:
    c, p = physics.client, entity.properties
    if not physics.tool_control:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: a URDF arm is driven by plans only (the named '
                              'programs drive the PR2 gripper); give a plan([...])')
    path, file = p['file'], Path(p['file']).name
    sdf = path.lower().endswith('.sdf')
    orientation = c.getQuaternionFromEuler(entity.pose.rpy)
    try:
        body_id = load_robot(c, path, entity.pose.xyz, orientation,
                             flags=c.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT)
    except ValueError as exc:
        raise _fact(entity.name, 'file', f'{file}: {exc}') from None
    if body_id < 0:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO, f'{entity.name}: cannot load {path}')
    facts = arm_facts(entity, joint_infos(c, body_id), sdf)
    infos, fingers = facts.infos, facts.fingers
    links = {j: info.link for j, info in enumerate(infos)}
    for link in range(-1, len(infos)):
        c.changeDynamics(body_id, link, lateralFriction=FRICTION)
    for joint, value in zip(facts.arm, facts.home):
        c.resetJointState(body_id, joint, value)
    gain = min(1.0, TRACKING_RATE / physics.settings.physics.rate_hz)
    if facts.revolute:
        hand = _linkage(physics, entity, body_id, facts, gain)
    else:
        for finger in fingers:
            c.resetJointState(body_id, finger, facts.start[finger])
        for child, (parent, _, _) in facts.mimics.items():
            _couple(c, body_id, parent, child, -1.0, 0.0)
        pads = p.get('pad_links') or [links[j] for j in fingers]
        hand = Gripper(c, entity.name, body_id, {'fingers': fingers}, [],
                       max_joint_force=max(infos[j].effort for j in fingers),
                       max_force=p['max_force'], max_opening=sum(infos[j].upper
                                                                 for j in fingers),
                       position_gain=gain, finger_links=pads)
    for joint, value in facts.held.items():
        c.resetJointState(body_id, joint, value)
        c.setJointMotorControl2(body_id, joint, c.POSITION_CONTROL, targetPosition=value,
                                force=HOLD_FORCE, positionGain=gain)
    physics.add_body(Body(entity.name, entity.cls, body_id, False, None, links=links,
                          driven=True, urdf=None if sdf else path))
    # Open, or held where a snapshot found the (prismatic) fingers until the plan moves them.
    hand.open(sum(facts.start.values()) if given_fingers(facts) else hand.max_opening,
              speed=0.1)
    physics.grippers[entity.name] = hand
    tool_orientation = c.getQuaternionFromEuler(p.get('tool_rpy', (0.0, 0.0, 0.0)))
    manipulator = Arm(c, entity.name, body_id, path, 1.0, (entity.pose.xyz, orientation),
                      facts.arm, facts.tool, p['tool_offset'], hand, gain, tool_orientation)
    manipulator.servo(*manipulator.tool_pose())
    physics.manipulators[entity.name] = manipulator


def given_fingers(facts: ArmFacts) -> bool:
    """Whether a snapshot gave the (prismatic) fingers' values: they start there, not
    open."""
    return not facts.revolute and any(facts.infos[j].name in facts.given
                                      for j in facts.fingers)


def check(name: str, properties: dict[str, Any]) -> None:
    """The URDF arm's facts are all given."""
    missing = [key for key in REQUIRED if key not in properties]
    if missing:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{name}: a urdf robot needs {", ".join(missing)}')
    named = [key for key in ('joint_names', 'joint_positions') if key in properties]
    if len(named) == 1:
        raise _fact(name, named[0], 'joint_names and joint_positions come together')
    if named and len(properties['joint_names']) != len(properties['joint_positions']):
        raise _fact(name, 'joint_positions', f'{len(properties["joint_positions"])} values '
                    f'for {len(properties["joint_names"])} joint names')
    given = [key for key in ('finger_open', 'finger_closed') if key in properties]
    if len(given) == 1:
        raise _fact(name, given[0], 'finger_open and finger_closed come together (or both '
                    "from the joints' limits)")
    for key in given:
        if len(properties[key]) != len(properties['finger_joints']):
            raise _fact(name, key, f'{len(properties[key])} values for '
                        f'{len(properties["finger_joints"])} finger joints')
    if given and any(o == c for o, c in zip(properties['finger_open'],
                                            properties['finger_closed'])):
        raise _fact(name, 'finger_open', 'a finger joint open where it is closed does not '
                    'move: finger_open and finger_closed differ for each')


def _fact(robot: str, key: str, message: str) -> ProjectionError:
    """The error of a fact ``key`` that does not fit the robot's model file."""
    return ProjectionError(ErrorKind.INVALID_SCENARIO, f'{robot}: {key}: {message}')


def _finger_kind(client: Any, robot: str, names: list[str], kinds: list[int]) -> bool:
    """Whether the finger joints are revolute (else prismatic); they are all one or all the
    other."""
    kind = {client.JOINT_PRISMATIC: 'prismatic', client.JOINT_REVOLUTE: 'revolute'}
    named = [kind.get(k, 'fixed or spherical') for k in kinds]
    if 'fixed or spherical' in named or len(set(named)) > 1:
        listed = ', '.join(f'{n} is {k}' for n, k in zip(names, named))
        raise _fact(robot, 'finger_joints', f'they must be all prismatic or all revolute '
                    f'({listed})')
    return named[0] == 'revolute'


def _linkage(physics: Physics, entity: Entity, body_id: int, facts: ArmFacts,
             gain: float) -> LinkageGripper:
    """The revolute fingers' gripper: its facts measured on the body before the world runs,
    the mimic joints geared to the fingers, the fingers open."""
    c, p, infos = physics.client, entity.properties, facts.infos
    linkage = linkage_facts(c, body_id, entity, facts)
    for child, (parent, multiplier, offset) in facts.mimics.items():
        _couple(c, body_id, parent, child, -1.0 / multiplier if multiplier else -1.0,
                -offset / multiplier if multiplier else 0.0)
        c.setJointMotorControl2(body_id, child, c.VELOCITY_CONTROL, targetVelocity=0.0,
                                force=0.0)
    for joint, value in linkage.start.items():
        c.resetJointState(body_id, joint, value)
    torques = [max(infos[j].effort, 0.0) or HOLD_FORCE for j in facts.fingers]
    hand = LinkageGripper(c, entity.name, body_id, facts.fingers, linkage.open,
                          linkage.closed, linkage.table, torques, p['max_force'], gain,
                          [infos[j].link for j in linkage.pads], linkage.carried)
    physics.step_hooks.append(hand.after_step)
    return hand


def _subtree(client: Any, body_id: int, joints: list[int],
             leaves: bool = False) -> list[int]:
    """The links that ``joints`` move (each joint's index is its child link's), sorted;
    with ``leaves``, those at the ends of the subtrees only, in the joints' order."""
    children: dict[int, list[int]] = {}
    for j in range(client.getNumJoints(body_id)):
        children.setdefault(client.getJointInfo(body_id, j)[16], []).append(j)
    found, todo = [], list(joints)
    while todo:
        link = todo.pop(0)
        todo.extend(children.get(link, []))
        if link not in found and not (leaves and link in children):
            found.append(link)
    return found if leaves else sorted(found)


def _middle(info: JointInfo) -> float:
    lower, upper = info.lower, info.upper
    return 0.0 if upper < lower else (lower + upper) / 2   # continuous joints: 0


def _rest(info: JointInfo) -> float:
    """Where a joint of the gripper that is neither finger nor mimic is held: 0, or the
    nearer limit."""
    lower, upper = info.lower, info.upper
    return 0.0 if upper < lower else min(max(0.0, lower), upper)


def _couple(client: Any, body_id: int, parent: int, child: int, ratio: float,
            target: float) -> None:
    """Joints that move as one: a gear keeping ``parent + ratio * child`` at ``target``
    (Bullet's gear; a URDF mimic ``child = m parent + o`` is ratio -1/m, target -o/m)."""
    gear = client.createConstraint(body_id, parent, body_id, child, client.JOINT_GEAR,
                                   (1, 0, 0), (0, 0, 0), (0, 0, 0))
    client.changeConstraint(gear, gearRatio=ratio, relativePositionTarget=target,
                            maxForce=COUPLING_FORCE, erp=0.2)


@functools.cache
def mimic_joints(urdf: str) -> dict[str, tuple[str, float, float]]:
    """The URDF's mimic joints: child joint name -> (the joint it follows, multiplier,
    offset)."""
    try:
        root = ET.parse(urdf).getroot()
    except (OSError, ET.ParseError):
        return {}
    return {joint.get('name'): (mimic.get('joint'), float(mimic.get('multiplier', 1.0)),
                                float(mimic.get('offset', 0.0)))
            for joint in root.iter('joint') for mimic in joint.iter('mimic')}


URDF_ARM = register(RobotModel('urdf', build, doc=__doc__.splitlines()[0],
                               properties=PROPERTIES, check=check))
