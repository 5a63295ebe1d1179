"""A snapshot of the robot's world: what :func:`take` reads from a :class:`RobotWorld` to
make a scenario of (``robot_world/2``, ``prolog/robot_world.pl``).

A snapshot is frozen when it is taken: the robot's description written as a model file,
every joint's position, every frame's pose in the world frame, each with its stamp and age.
It is kept in the scenario (and so in every bag's ``/projection/info``), so that a
projection made from the live world can be run again, and drawn, without the robot.

What is not there yet (no description, a frame no transform names, a joint with no state)
may still arrive: :func:`take` says so (:class:`NotYet`) and its caller waits and asks
again, until its ``wait`` runs out. What is wrong (a URDF that does not parse, a mesh not
found, a stale frame, a joint outside its limits) is a :class:`WorldError` at once.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any

from projection_server.geometry import rpy_of
from projection_server.world import description as urdf
from projection_server.world.state import RobotWorld
from projection_server.world.transforms import TransformError

__all__ = ['NotYet', 'Options', 'WorldError', 'take']

# A description's parse and its written file, per text: a robot's description does not
# change between snapshots, and a snapshot should cost milliseconds.
_WRITTEN: dict[str, tuple[urdf.RobotDescription, str]] = {}


class WorldError(Exception):
    """What makes a snapshot impossible, as an ISO error: ``formal`` (``existence_error``,
    ``domain_error``, ``permission_error``), ``type`` (its first argument: ``frame``,
    ``joint_state``, ``mesh``, ...), ``culprit`` and a message that names it."""

    def __init__(self, formal: str, type_: str, culprit: Any, message: str):
        super().__init__(message)
        self.formal, self.type, self.culprit, self.message = formal, type_, culprit, message

    def as_dict(self) -> dict[str, Any]:
        return {'formal': self.formal, 'type': self.type, 'culprit': self.culprit,
                'message': self.message}


class NotYet(WorldError):
    """Something the snapshot needs has not arrived (yet): the error it is at the end."""


@dataclass(frozen=True)
class Options:
    """What a snapshot reads: the world frame, the object frames, the oldest a frame or
    joint state may be [s]."""

    world_frame: str = 'map'
    frames: tuple[str, ...] = ()
    max_age: float = 1.0


def take(world: RobotWorld, options: Options) -> dict[str, Any]:
    """The snapshot of ``world`` now.

    Returns a dict: ``robot`` (``name``, ``file``, ``joint_names``, ``joint_positions``,
    ``pose`` of its root link in the world frame as ``xyz``/``rpy``), ``frames`` (each
    requested frame's pose, ``xyz``/``rpy``) and ``snapshot`` (what it was taken from:
    stamps, ages, quaternions, the description's hash: JSON data).

    Raises:
        NotYet: no description, an unknown frame or a joint without state, so far.
        WorldError: a malformed description or mesh, a stale frame or joint state, a
            joint outside its limits, frames not connected to the world frame.
    """
    now = world.now()
    received = world.description()
    topic = world.topics.get('robot_description', '/robot_description')
    if received is None:
        raise NotYet('existence_error', 'robot_description', topic,
                     f'no robot description has arrived on {topic}')
    robot, path = _written(received.text, topic)
    joints = world.joints()
    names = robot.moving_joints()
    missing = [n for n in names if n not in joints]
    if missing:
        topic_j = world.topics.get('joint_states', '/joint_states')
        raise NotYet('existence_error', 'joint_state', missing[0], (
            f'joint {missing[0]} of {robot.name} has no state on {topic_j} yet'
            + (f' (nor {", ".join(missing[1:])})' if len(missing) > 1 else '')))
    limit = int(options.max_age * 1e9)
    joint_record = {}
    for name in names:
        state = joints[name]
        age = (now - state.stamp) / 1e9
        if now - state.stamp > limit:
            raise WorldError('domain_error', 'fresh_joint_state', name, (
                f'the state of joint {name} is {age:.2f} s old (max_age {options.max_age} s)'))
        joint = robot.joints[name]
        if not urdf.within_limits(joint, state.position):
            raise WorldError('domain_error', 'joint_limits', name, (
                f'joint {name} is at {state.position:.4f}, outside its limits '
                f'[{joint.lower}, {joint.upper}] in the URDF of {robot.name}'))
        joint_record[name] = {'position': state.position, 'stamp': state.stamp,
                              'age': round(max(age, 0.0), 6)}
    frames, frame_record = {}, {}
    for frame in (robot.root_link, *options.frames):
        pose, stamp = _lookup(world, options.world_frame, frame)
        age = None if stamp is None else (now - stamp) / 1e9
        if stamp is not None and now - stamp > limit:
            raise WorldError('domain_error', 'fresh_frame', frame, (
                f'frame {frame} is {age:.2f} s old in {options.world_frame} '
                f'(max_age {options.max_age} s)'))
        position, quaternion = (tuple(float(v) for v in pose[0]),
                                tuple(float(v) for v in pose[1]))
        frames[frame] = {'xyz': list(position), 'rpy': list(rpy_of(quaternion))}
        # A static frame never ages: stamp 0, age 0. A stamp a little after `now` (the
        # transform arrived while this ran) is no age either.
        frame_record[frame] = {'xyz': list(position), 'quaternion': list(quaternion),
                               'stamp': stamp or 0, 'age': round(max(age or 0.0, 0.0), 6)}
    return {
        'robot': {'name': robot.name, 'file': path, 'joint_names': names,
                  'joint_positions': [joints[n].position for n in names],
                  'pose': frames[robot.root_link]},
        'frames': {f: frames[f] for f in options.frames},
        'snapshot': {'stamp': now, 'world_frame': options.world_frame,
                     'robot_description': {'topic': topic, 'robot': robot.name,
                                           'root_link': robot.root_link,
                                           'sha256': robot.sha256,
                                           'received': received.received},
                     'joints': joint_record, 'frames': frame_record},
    }


def _written(text: str, topic: str) -> tuple[urdf.RobotDescription, str]:
    cached = _WRITTEN.get(text)
    if cached is None:
        try:
            robot = urdf.parse(text, topic)
            cached = robot, urdf.write(robot)
        except urdf.DescriptionError as exc:
            formal, type_ = {'malformed': ('domain_error', 'urdf'),
                             'mesh_missing': ('existence_error', 'mesh'),
                             'mesh_outside': ('permission_error', 'mesh')}[exc.kind]
            raise WorldError(formal, type_, exc.culprit, exc.message) from None
        if len(_WRITTEN) > 16:   # a node sees few descriptions; keep the recent ones
            _WRITTEN.pop(next(iter(_WRITTEN)))
        _WRITTEN[text] = cached
    return cached


def _lookup(world: RobotWorld, target: str, frame: str):
    try:
        return world.transforms.lookup(target, frame)
    except TransformError as exc:
        if exc.kind == 'unknown':
            raise NotYet('existence_error', 'frame', exc.frame, exc.message) from None
        if exc.kind == 'unconnected':
            raise NotYet('existence_error', 'transform', f'{target} -> {frame}',
                         exc.message) from None
        raise WorldError('domain_error', 'transform_time', frame, exc.message) from None


