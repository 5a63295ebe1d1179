"""Writing one projection's bag: :class:`BagWriter`."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, TYPE_CHECKING

from projection_server.bags.cdr import CdrTemplate, definition
from projection_server.bags.mcap import writer_class
from projection_server.bags.schema import offered_qos, typestore
from projection_server.errors import ErrorKind, ProjectionError

if TYPE_CHECKING:
    from collections.abc import Iterable

__all__ = ['BagWriter']


class BagWriter:
    """Writes one new bag; topics are added on their first message, in that order.

    Use as a context manager. The bag must not exist (rosbags never overwrites).
    """

    def __init__(self, path: str | os.PathLike[str], storage: str = 'mcap'):
        from rosbags.rosbag2 import StoragePlugin, WriterError

        plugin = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}[storage]
        self.path = Path(path)
        self._store = typestore()
        try:
            self._writer = writer_class()(self.path, version=9, storage_plugin=plugin)
        except WriterError as exc:
            raise ProjectionError(ErrorKind.BAG_ERROR, str(exc)) from exc
        self._connections: dict[str, Any] = {}
        self._write_many = getattr(self._writer, 'write_many', None) or self._write_each

    def __enter__(self) -> BagWriter:
        from rosbags.rosbag2 import WriterError

        try:
            self._writer.open()
        except WriterError as exc:
            raise ProjectionError(ErrorKind.BAG_ERROR, str(exc)) from exc
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._writer.close()

    def write(self, topic: str, message: Any, t_ns: int) -> None:
        """Serialize ``message`` (a typestore dataclass) onto ``topic`` at ``t_ns``."""
        msgtype = message.__msgtype__
        self.write_cdr(topic, msgtype, self._store.serialize_cdr(message, msgtype), t_ns)

    def write_cdr(self, topic: str, msgtype: str, data: bytes, t_ns: int) -> None:
        """Write ``data``, a ``msgtype`` message serialized as CDR, onto ``topic``."""
        connection = self._connections.get(topic)
        if connection is None:
            msgdef, digest = definition(msgtype)
            connection = self._writer.add_connection(
                topic, msgtype, msgdef=msgdef, rihs01=digest,
                offered_qos_profiles=[offered_qos(topic)])
            self._connections[topic] = connection
        self._writer.write(connection, t_ns, data)

    def write_sample(self, t_ns: int, messages: Iterable[tuple[str, str, bytes]]) -> None:
        """Write the ``(topic, msgtype, CDR data)`` of one monitoring step, all at ``t_ns``:
        the bytes of :meth:`write_cdr` of each in turn, in one call."""
        connections = self._connections
        batch = []
        for topic, msgtype, data in messages:
            connection = connections.get(topic)
            if connection is None:   # the topic's first message adds its connection
                if batch:
                    self._write_many(t_ns, batch)
                    batch = []
                self.write_cdr(topic, msgtype, data, t_ns)
                continue
            batch.append((connection, data))
        if batch:
            self._write_many(t_ns, batch)

    def write_samples(self, samples: Iterable[tuple[int, list[tuple[str, str, bytes]]]]
                      ) -> None:
        """:meth:`write_sample` of each ``(t_ns, messages)``, the times in order: the same
        bytes, in one call of the storage's where it can."""
        write_batches = getattr(self._writer, 'write_batches', None)
        connections = self._connections
        batches = []
        for t_ns, messages in samples:
            batch = []
            for topic, _, data in messages:
                connection = connections.get(topic)
                if connection is None:
                    break
                batch.append((connection, data))
            else:
                if write_batches is not None:
                    batches.append((t_ns, batch))
                    continue
            if batches:   # what came before, then this sample as write_sample writes it
                write_batches(batches)
                batches = []
            self.write_sample(t_ns, messages)
        if batches:
            write_batches(batches)

    def template(self, msgtype: str, prototype: Any,
                 variable: tuple[str, ...]) -> CdrTemplate:
        """:class:`CdrTemplate` of ``prototype`` (kept per process: see :func:`template`)."""
        return CdrTemplate(self._store, msgtype, prototype, variable)

    def new(self, msgtype: str, **fields: Any) -> Any:
        """A message of ``msgtype`` from the writer's typestore."""
        return self._store.types[msgtype](**fields)

    def type(self, msgtype: str) -> Any:
        """The message class of ``msgtype`` (for its constants)."""
        return self._store.types[msgtype]

    def _write_each(self, t_ns: int, batch: list[tuple[Any, bytes]]) -> None:
        # rosbags' own writer (another rosbags than bags.mcap's): one message at a time.
        for connection, data in batch:
            self._writer.write(connection, t_ns, data)
