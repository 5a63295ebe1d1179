"""What a projection's bag holds: its topics, their QoS, the message types, and the
records a bag's messages stand for (the monitor writes them, the timeline reads them).

Every stage that writes or reads a projection's log shares this vocabulary; it imports no
other part of the project but its error.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import os
from pathlib import Path
from typing import Any, NamedTuple, TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = [
    'INTERFACE_PACKAGE',
    'LATCHED',
    'PARTICLES_NS',
    'REFERENCE_LINKS',
    'Record',
    'TOPICS',
    'TfBlock',
    'TOPIC_TYPES',
    'is_latched',
    'message_definitions',
    'offered_qos',
    'robot_description_topic',
    'typestore',
]

INTERFACE_PACKAGE = 'projection_interfaces'
TOPICS = {
    'info': '/projection/info',
    'tf': '/tf',
    'tf_static': '/tf_static',
    'markers': '/projection/markers',
    'contacts': '/projection/contacts',
    'gripper': '/projection/gripper',
    'objects': '/projection/objects',
    'task': '/projection/task',
    'batter': '/projection/batter',
    'bonds': '/projection/bonds',
    'clock': '/clock',
    'robot_description': '/robot_description',
}
# What each topic of :data:`TOPICS` carries: its message type and what one message says.
# The documentation's table of a bag's topics is made from this one; a test checks it
# against the connections of a projection's bag.
TOPIC_TYPES = {
    'info': ('projection_interfaces/msg/ProjectionInfo',
             'once, at 0: the scenario, program, parameters and physics settings'),
    'tf': ('tf2_msgs/msg/TFMessage',
           'every sample: each object\'s pose and each robot\'s links, as a chain under the robot'),
    'tf_static': ('tf2_msgs/msg/TFMessage', 'once: the frames that never move'),
    'markers': ('visualization_msgs/msg/MarkerArray',
                'every sample: each object\'s shape; a particle fluid as one SPHERE_LIST'),
    'contacts': ('projection_interfaces/msg/ContactArray',
                 'every sample: the contacts between bodies, aggregated since the last one'),
    'gripper': ('projection_interfaces/msg/GripperState',
                'every sample: each robot\'s gripper command, opening and finger forces'),
    'objects': ('projection_interfaces/msg/ObjectStateArray',
                'every sample: each modelled object\'s load, load limit and whether it is broken'),
    'task': ('projection_interfaces/msg/TaskState',
             'every sample: each robot\'s plan step or program phase and its target'),
    'batter': ('std_msgs/msg/Float64MultiArray',
               'every sample, per particle fluid: its temperatures, then its set flags'),
    'bonds': ('std_msgs/msg/UInt32MultiArray',
              'at the first sample and when they change: the bonds between set particles'),
    'clock': ('rosgraph_msgs/msg/Clock', 'every sample: the simulated time'),
    'robot_description': ('std_msgs/msg/String',
                          'once: the first robot\'s URDF, its links named as their /tf frames '
                          '(another robot R\'s on /R/robot_description)'),
}
# Published once and latched: late subscribers must still get it. A scenario's first robot
# describes itself on /robot_description, every other robot R on /R/robot_description
# (robot_description_topic).
LATCHED = frozenset({TOPICS['tf_static'], TOPICS['info'], TOPICS['robot_description']})


def robot_description_topic(robot: str, index: int) -> str:
    """The topic of the URDF of the ``index``-th robot (from 0), named ``robot``."""
    return TOPICS['robot_description'] if index == 0 else f'/{robot}/robot_description'


def is_latched(topic: str) -> bool:
    """Whether ``topic`` is published once and latched (:data:`LATCHED`, and every
    robot's description)."""
    return topic in LATCHED or topic.endswith(TOPICS['robot_description'])


def offered_qos(topic: str) -> Any:
    """The QoS profile a publisher of ``topic`` offers: reliable, keep last; transient
    local (depth 1) for the latched topics, volatile (depth 100) for the others, as
    tf2_ros' broadcasters and rosbag2's defaults do."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)

    infinite = QosTime(sec=9223372036, nsec=854775807)   # RMW_DURATION_INFINITE
    latched = is_latched(topic)
    return Qos(history=QosHistory.KEEP_LAST, depth=1 if latched else 100,
               reliability=QosReliability.RELIABLE,
               durability=QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
               deadline=infinite, lifespan=infinite, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=infinite, avoid_ros_namespace_conventions=False)


def message_definitions() -> dict[str, str]:
    """``{'projection_interfaces/msg/Name': msg text}`` of the project's messages.

    Read from the installed share dir of ``projection_interfaces`` when it is on
    ``AMENT_PREFIX_PATH`` and has messages, else from the source tree's ``msg_defs/msg``.
    """
    candidates = [Path(prefix) / 'share' / INTERFACE_PACKAGE / 'msg'
                  for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
                  if prefix]
    candidates.append(Path(__file__).resolve().parents[2] / 'msg_defs' / 'msg')
    for directory in candidates:
        files = sorted(directory.glob('*.msg'))
        if files:
            return {f'{INTERFACE_PACKAGE}/msg/{f.stem}': f.read_text() for f in files}
    raise ProjectionError(ErrorKind.BAG_ERROR, f'no {INTERFACE_PACKAGE} message definitions found')


@functools.cache
def typestore() -> Typestore:
    """ROS 2 Jazzy's types plus the project's messages (built once per process)."""
    from rosbags.typesys import get_types_from_msg, get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for name, text in message_definitions().items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


# A deformable body (a pancake) logs its segments as link frames ``body/link``; the two of
# these names are on its rim, a quarter turn apart, and give its upper side's normal.
REFERENCE_LINKS = ('rim_a', 'rim_b')

# The namespace of the particle fluids' SPHERE_LIST markers on the markers topic (one
# marker per fluid, text = the fluid's name).
PARTICLES_NS = 'particles'


class Record(NamedTuple):
    """What the monitor logged on one topic at one time, as plain data: what a projection's
    timeline is made from, in the worker from the monitor's own records, or read back from
    a bag (:func:`projection_server.bags.read_records`).

    ``kind`` and ``data``:

    * ``info``: the ``ProjectionInfo`` message;
    * ``tf_static``, ``tf``: ``[(parent frame, child frame, (x, y, z), (x, y, z, w)), ...]``;
    * ``tf_block``: the ``/tf`` of many samples, as the monitor keeps it (a bag read back
      gives a ``tf`` record per message instead): a :class:`TfBlock`, at its first time;
    * ``contacts``: ``[(body_a, link_a, body_b, link_b, normal force, normal), ...]``, the
      normal ``(x, y, z)`` pointing from b to a;
    * ``gripper``: ``(name, command, finger links)``;
    * ``objects``: ``[(name, load, load limit, broken), ...]``;
    * ``task``: ``(robot, step, action, target)``, one per robot (of tasks that report
      their state);
    * ``particles``: ``{fluid: positions (n, 3)}``;
    * ``batter``: ``{fluid: (temperatures (n,) [deg C], set flags (n,) bool)}``, every
      sample, of fluids whose heat is simulated;
    * ``bonds``: ``{fluid: bonded particle index pairs (m, 2)}``, at the first sample and
      whenever the bonds in force change.
    """

    kind: str
    t_ns: int
    data: Any


@dataclass(frozen=True, eq=False)
class TfBlock:
    """The ``/tf`` of n samples that have the same k frames: their times [ns], the frames
    ``((parent, child), ...)`` and the poses, as in the messages. Two are equal when all of
    these are (the numbers compared as ``==`` compares floats)."""

    times: Any          # (n,) int64 [ns]
    frames: tuple[tuple[str, str], ...]
    positions: Any      # (n, k, 3) [m]
    quaternions: Any    # (n, k, 4) (x, y, z, w)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TfBlock):
            return NotImplemented
        return (self.frames == other.frames
                and all(np.array_equal(a, b) for a, b in (
                    (self.times, other.times), (self.positions, other.positions),
                    (self.quaternions, other.quaternions))))

    __hash__ = None   # type: ignore[assignment]   (numpy arrays are not hashable)
