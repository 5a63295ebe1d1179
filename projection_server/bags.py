"""Projection logs as rosbag2 bags (MCAP), written and read with rosbags.

One bag per projection. Standard message types where they fit (``tf2_msgs/TFMessage``,
``visualization_msgs/MarkerArray``), the project's ``projection_interfaces`` messages for
the monitored state. Timestamps are integer nanoseconds of simulated time from the start of
the projection.

Topics (:data:`TOPICS`):

========================  ===================================================================
``/projection/info``      ``ProjectionInfo``, once at t = 0: scenario, program, parameters,
                          settings, code version
``/tf_static``            ``TFMessage``, once: poses of static bodies (table, floor...)
``/tf``                   ``TFMessage``, every monitoring step: poses of the other bodies
                          (parent frame ``world``) and of their links: a robot's links as a
                          chain under the robot (each in its URDF parent link's frame), other
                          bodies' links in ``world``
``/clock``                ``rosgraph_msgs/Clock``, every monitoring step: the simulated time
``/projection/markers``   ``MarkerArray``: shapes of the bodies, at t = 0 and on each change
``/projection/contacts``  ``ContactArray``, every monitoring step
``/projection/gripper``   ``GripperState``, every monitoring step, one per gripper
``/projection/objects``   ``ObjectStateArray``, every monitoring step (loads, broken flags)
========================  ===================================================================

Each topic records the QoS its publisher would offer (:func:`offered_qos`), as rosbag2
does, so that ``ros2 bag play`` republishes ``/tf_static`` transient-local (a late RViz
still gets the static frames) and everything reliable.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Any, TYPE_CHECKING

from projection_server.simulation.errors import ProjectionError

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator

    from rosbags.typesys.store import Typestore

__all__ = [
    'BagWriter',
    'INTERFACE_PACKAGE',
    'LATCHED',
    'TOPICS',
    'message_definitions',
    'offered_qos',
    'read_bag',
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
    'clock': '/clock',
}
# Published once and latched: late subscribers must still get it.
LATCHED = frozenset({TOPICS['tf_static'], TOPICS['info']})


def offered_qos(topic: str) -> Any:
    """The QoS profile a publisher of ``topic`` offers: reliable, keep last; transient
    local (depth 1) for the latched topics, volatile (depth 100) for the others, as
    tf2_ros' broadcasters and rosbag2's defaults do."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)

    infinite = QosTime(sec=9223372036, nsec=854775807)   # RMW_DURATION_INFINITE
    latched = topic in LATCHED
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
    candidates.append(Path(__file__).resolve().parents[1] / 'msg_defs' / 'msg')
    for directory in candidates:
        files = sorted(directory.glob('*.msg'))
        if files:
            return {f'{INTERFACE_PACKAGE}/msg/{f.stem}': f.read_text() for f in files}
    raise ProjectionError('bag_error', f'no {INTERFACE_PACKAGE} message definitions found')


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


class BagWriter:
    """Writes one new bag; topics are added on their first message, in that order.

    Use as a context manager. The bag must not exist (rosbags never overwrites).
    """

    def __init__(self, path: str | os.PathLike[str], storage: str = 'mcap'):
        from rosbags.rosbag2 import StoragePlugin, Writer, WriterError

        plugin = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}[storage]
        self.path = Path(path)
        self._store = typestore()
        try:
            self._writer = Writer(self.path, version=Writer.VERSION_LATEST,
                                  storage_plugin=plugin)
        except WriterError as exc:
            raise ProjectionError('bag_error', str(exc)) from exc
        self._connections: dict[str, Any] = {}

    def __enter__(self) -> BagWriter:
        from rosbags.rosbag2 import WriterError

        try:
            self._writer.open()
        except WriterError as exc:
            raise ProjectionError('bag_error', str(exc)) from exc
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._writer.close()

    def write(self, topic: str, message: Any, t_ns: int) -> None:
        """Serialize ``message`` (a typestore dataclass) onto ``topic`` at ``t_ns``."""
        msgtype = message.__msgtype__
        connection = self._connections.get(topic)
        if connection is None:
            connection = self._writer.add_connection(
                topic, msgtype, typestore=self._store,
                offered_qos_profiles=[offered_qos(topic)])
            self._connections[topic] = connection
        self._writer.write(connection, int(t_ns), self._store.serialize_cdr(message, msgtype))

    def new(self, msgtype: str, **fields: Any) -> Any:
        """A message of ``msgtype`` from the writer's typestore."""
        return self._store.types[msgtype](**fields)

    def type(self, msgtype: str) -> Any:
        """The message class of ``msgtype`` (for its constants)."""
        return self._store.types[msgtype]


def read_bag(path: str | os.PathLike[str],
             topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, Any]]:
    """Yield ``(topic, t_ns, message)`` of a bag in time order, using its embedded types.

    Raises:
        ProjectionError: kind ``bag_error`` if the bag is missing or unreadable.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError

    path = Path(path)
    wanted = set(topics) if topics is not None else None
    try:
        with AnyReader([path], default_typestore=typestore()) as reader:
            connections = [c for c in reader.connections
                           if wanted is None or c.topic in wanted]
            for connection, t_ns, raw in reader.messages(connections=connections):
                yield connection.topic, t_ns, reader.deserialize(raw, connection.msgtype)
    except (AnyReaderError, FileNotFoundError) as exc:
        raise ProjectionError('bag_error', f'cannot read bag {path}: {exc}') from exc
