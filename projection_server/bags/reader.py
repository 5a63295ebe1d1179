"""Reading a projection's bag: its messages, or the monitor's records they stand for."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.bags.schema import PARTICLES_NS, Record, TOPICS, typestore
from projection_server.errors import ErrorKind, ProjectionError

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator

__all__ = ['read_bag', 'read_records', 'records_of']


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
        raise ProjectionError(ErrorKind.BAG_ERROR, f'cannot read bag {path}: {exc}') from exc


# The topics a projection's records are read from, and the record kind of each (the
# markers topic gives only its particles).
_KINDS = {TOPICS[name]: name for name in ('info', 'tf_static', 'tf', 'contacts', 'gripper',
                                          'objects', 'task', 'batter', 'bonds')}
_RECORD_TOPICS = [*_KINDS, TOPICS['markers']]


def read_records(path: str | os.PathLike[str]) -> Iterator[Record]:
    """The monitor's records of the projection logged in the bag at ``path``: what its
    worker had in memory when it made the bag.

    Raises:
        ProjectionError: kind ``bag_error`` if the bag is missing or unreadable.
    """
    return records_of(read_bag(path, _RECORD_TOPICS))


def records_of(messages: Iterable[tuple[str, int, Any]]) -> Iterator[Record]:
    """The monitor's records of bag messages ``(topic, t_ns, message)``, in their order."""
    for topic, t_ns, msg in messages:
        kind = _KINDS.get(topic)
        if kind in ('tf', 'tf_static'):
            yield Record(kind, t_ns, [
                (tr.header.frame_id, tr.child_frame_id,
                 (tr.transform.translation.x, tr.transform.translation.y,
                  tr.transform.translation.z),
                 (tr.transform.rotation.x, tr.transform.rotation.y, tr.transform.rotation.z,
                  tr.transform.rotation.w)) for tr in msg.transforms])
        elif kind == 'contacts':
            yield Record(kind, t_ns, [(c.body_a, c.link_a, c.body_b, c.link_b, c.normal_force,
                                       (c.normal.x, c.normal.y, c.normal.z)) for c in msg.contacts])
        elif kind == 'gripper':
            yield Record(kind, t_ns, (msg.name, msg.command, msg.finger_links))
        elif kind == 'objects':
            yield Record(kind, t_ns, [(o.name, o.load, o.load_limit, o.broken)
                                      for o in msg.objects])
        elif kind == 'task':
            yield Record(kind, t_ns, (msg.robot, msg.step, msg.action, msg.target))
        elif kind == 'info':
            yield Record(kind, t_ns, msg)
        elif kind == 'batter':
            count = msg.layout.dim[1].size
            data = np.asarray(msg.data, dtype=float)
            yield Record(kind, t_ns, {msg.layout.dim[0].label: (data[:count].copy(),
                                                                data[count:] > 0.5)})
        elif kind == 'bonds':
            yield Record(kind, t_ns, {msg.layout.dim[0].label: np.asarray(
                msg.data, dtype=np.int64).reshape(-1, 2)})
        elif topic == TOPICS['markers']:   # only the particles
            particles = {marker.text: np.array([(q.x, q.y, q.z) for q in marker.points],
                                               dtype=float).reshape(-1, 3)
                         for marker in msg.markers if marker.ns == PARTICLES_NS}
            if particles:
                yield Record('particles', t_ns, particles)
