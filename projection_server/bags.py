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

Messages written every monitoring step have a layout that does not change from one sample
to the next (the same frames, the same contact pairs, the same particles): a
:class:`CdrTemplate` made once from a prototype message serializes them by writing the
numbers into the prototype's CDR bytes, with the bytes rosbags' ``serialize_cdr`` gives.
What does not depend on the messages (message definitions and hashes, each topic's QoS as
YAML, the layout of ``metadata.yaml``) is computed once per process.
"""

from __future__ import annotations

from collections import defaultdict
import copy
from fnmatch import fnmatchcase
import functools
from io import BytesIO, StringIO
import os
from pathlib import Path
import re
import struct
from typing import Any, Callable, TYPE_CHECKING

from projection_server.simulation.errors import ProjectionError

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator

    from rosbags.typesys.store import Typestore

__all__ = [
    'BagWriter',
    'CdrTemplate',
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
        from rosbags.rosbag2 import StoragePlugin, WriterError

        plugin = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}[storage]
        self.path = Path(path)
        self._store = typestore()
        try:
            self._writer = _writer_class()(self.path, version=9, storage_plugin=plugin)
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
        self.write_cdr(topic, msgtype, self._store.serialize_cdr(message, msgtype), t_ns)

    def write_cdr(self, topic: str, msgtype: str, data: bytes, t_ns: int) -> None:
        """Write ``data``, a ``msgtype`` message serialized as CDR, onto ``topic``."""
        connection = self._connections.get(topic)
        if connection is None:
            msgdef, digest = _definition(msgtype)
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
                    self._writer.write_many(t_ns, batch)
                    batch = []
                self.write_cdr(topic, msgtype, data, t_ns)
                continue
            batch.append((connection, data))
        if batch:
            self._writer.write_many(t_ns, batch)

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


class CdrTemplate:
    """Serializes messages that differ from a prototype only in some of their numbers.

    ``variable`` are patterns (:func:`fnmatch.fnmatchcase`) of the dotted paths of the
    numeric fields that vary, with sequence elements as indices (``transforms.0.header.
    stamp.sec``; ``transforms.*.transform.*`` matches every number of every transform's
    pose). Strings and sequence lengths are those of the prototype, and so are the numbers
    no pattern matches. :meth:`pack` takes the varying numbers in the order of the message
    definition and returns the CDR bytes (little endian, with its encapsulation header)
    that rosbags' ``serialize_cdr`` gives of the message with those numbers: the message is
    one ``struct`` format of constant byte runs and numbers.
    """

    def __init__(self, store: Typestore, msgtype: str, prototype: Any,
                 variable: tuple[str, ...]):
        self.msgtype = msgtype
        self.variable = variable
        self._store = store
        self._prototype = copy.deepcopy(prototype)
        self._tokens: list[tuple[str, Any]] = [('c', b'\x00\x01\x00\x00')]
        self._pos = 0
        self._message(prototype, msgtype, '')
        fmt, consts, args, count = '<', {}, [], 0
        run: list[bytes] = []
        for kind, value in [*self._tokens, ('end', None)]:
            if kind == 'c':
                run.append(value)
                continue
            if run:
                name = f'c{len(consts)}'
                consts[name] = b''.join(run)
                fmt += f'{len(consts[name])}s'
                args.append(name)
                run = []
            if kind == 'v':
                fmt += value
                args.append(f'v[{count}]')
                count += 1
        consts['pack'] = struct.Struct(fmt).pack
        self.count = count
        self.size = struct.calcsize(fmt)
        # One call of a compiled struct format, as rosbags' serializers are generated code.
        self.pack: Callable[[Any], bytes] = eval(   # noqa: S307 (generated, no input)
            f'lambda v: pack({", ".join(args)})', consts)
        del self._tokens

    def prototype(self) -> Any:
        """A copy of the message the template was made of."""
        return copy.deepcopy(self._prototype)

    def _align(self, size: int) -> None:
        pad = -self._pos % size
        if pad:
            self._tokens.append(('c', bytes(pad)))
            self._pos += pad

    def _number(self, basetype: str, value: Any, path: str) -> None:
        code, size = _CDR_NUMBERS[basetype]
        self._align(min(size, 8))
        if any(fnmatchcase(path, pattern) for pattern in self.variable):
            self._tokens.append(('v', code))
        else:
            self._tokens.append(('c', struct.pack('<' + code, value)))
        self._pos += size

    def _string(self, value: str) -> None:
        raw = value.encode()
        self._align(4)
        self._tokens.append(('c', struct.pack('<I', len(raw) + 1) + raw + b'\x00'))
        self._pos += 4 + len(raw) + 1

    def _value(self, desc: Any, value: Any, path: str) -> None:
        from rosbags.interfaces import Nodetype

        kind, detail = desc
        if kind == Nodetype.NAME:
            self._message(value, detail, path + '.')
        elif kind == Nodetype.BASE:
            if detail[0] == 'string':
                self._string(value)
            else:
                self._number(detail[0], value, path)
        elif kind == Nodetype.ARRAY:
            for index, item in enumerate(value):
                self._value(detail[0], item, f'{path}.{index}')
        else:   # a sequence: its length, then its elements
            self._align(4)
            self._tokens.append(('c', struct.pack('<I', len(value))))
            self._pos += 4
            for index, item in enumerate(value):
                self._value(detail[0], item, f'{path}.{index}')

    def _message(self, message: Any, msgtype: str, prefix: str) -> None:
        for name, desc in self._store.get_msgdef(msgtype).fields:
            self._value(desc, getattr(message, name), prefix + name)


# Base type -> (struct code, size); the strings are handled apart.
_CDR_NUMBERS = {
    'bool': ('?', 1), 'byte': ('B', 1), 'char': ('B', 1), 'int8': ('b', 1),
    'uint8': ('B', 1), 'int16': ('h', 2), 'uint16': ('H', 2), 'int32': ('i', 4),
    'uint32': ('I', 4), 'int64': ('q', 8), 'uint64': ('Q', 8), 'float32': ('f', 4),
    'float64': ('d', 8),
}


@functools.cache
def _definition(msgtype: str) -> tuple[str, str]:
    """``(message definition, RIHS01 hash)`` of ``msgtype``, as a bag's connection has it."""
    store = typestore()
    return store.generate_msgdef(msgtype, ros_version=2)[0], store.hash_rihs01(msgtype)


@functools.cache
def _qos_yaml(profiles: tuple[Any, ...]) -> str:
    """The offered QoS profiles as rosbags writes them into a bag (version 9)."""
    from rosbags.rosbag2.metadata import dump_qos_v9

    return _dump_yaml(dump_qos_v9(list(profiles))).strip()


def _dump_yaml(data: Any) -> str:
    from ruamel.yaml import YAML

    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    stream = StringIO()
    yaml.dump(data, stream)
    return stream.getvalue()


# An MCAP message record's opcode and length, then the message header: channel, sequence,
# log time, publish time.
_MCAP_MESSAGE = struct.Struct('<BQHIQQ')

# Integers that stand for a bag's numbers in a metadata.yaml layout: distinct, and written
# by YAML as plain digits that occur nowhere else in the file.
_SENTINELS = tuple(9_100_000_000_000_000_000 + 1_000_003 * i for i in range(64))
_SENTINEL_FILE = 'x0sentinel0x.mcap'
_PLAIN_FILE = re.compile(r'[A-Za-z0-9_][A-Za-z0-9_.-]*\.mcap')


@functools.cache
def _writer_class() -> type:
    """rosbags' bag writer, with what it computes with ruamel YAML per connection and at
    close (the topics' QoS, ``metadata.yaml``) computed once per process and topic layout
    (the YAML text is the same, byte for byte)."""
    from importlib.metadata import version

    from rosbags.interfaces import ConnectionExtRosbag2, MessageDefinition, \
        MessageDefinitionFormat
    from rosbags.interfaces import Connection
    from rosbags.rosbag2 import CompressionMode, StoragePlugin, Writer, WriterError
    from rosbags.rosbag2.metadata import dump_qos_v9
    from rosbags.rosbag2.storage_mcap import (McapWriter, PendingChunk, write_record,
                                              write_string, write_uint16, write_uint32,
                                              write_uint64)

    rosbags_version = version('rosbags')

    class _Mcap(McapWriter):
        def __init__(self, path: Path, compression: CompressionMode) -> None:
            if compression != CompressionMode.NONE:
                super().__init__(path, compression)
                return
            # rosbags' own, but for the version of rosbags in the header: asked once per
            # process, not of the package metadata for every bag.
            self.path = path / f'{path.name}.mcap'
            self.bio = self.path.open('xb')
            self.bio.write(b'\x89MCAP\x30\r\n')
            rec = BytesIO()
            write_string(rec, 'ros2')
            write_string(rec, f'rosbags-{rosbags_version}')
            write_record(self.bio, 0x01, rec)
            self.schemas, self.channels, self.chunks = [], [], []
            self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
            self.compression = ''
            self.compressor = lambda data: data
            self.message_start_time = 2**63 - 1
            self.message_end_time = 0
            self.channel_stats = {}

        def write(self, connection: Any, timestamp: int, data: bytes) -> None:
            # rosbags' message record, packed in one call instead of a BytesIO per message.
            self.message_start_time = min(timestamp, self.message_start_time)
            self.message_end_time = max(timestamp, self.message_end_time)
            self.channel_stats[connection.id] += 1
            chunk = self.chunk
            chunk.message_start_time = min(timestamp, chunk.message_start_time)
            chunk.message_end_time = max(timestamp, chunk.message_end_time)
            bio = chunk.bio
            chunk.msgs[connection.id].append((timestamp, bio.tell()))
            bio.write(_MCAP_MESSAGE.pack(0x05, 22 + len(data), connection.id, 0, timestamp,
                                         timestamp))
            bio.write(data)
            if bio.tell() > 2**20:
                self.close_chunk()

        def write_many(self, timestamp: int, batch: list[tuple[Any, bytes]]) -> None:
            """:meth:`write` of each ``(connection, data)``, all at ``timestamp``."""
            self.message_start_time = min(timestamp, self.message_start_time)
            self.message_end_time = max(timestamp, self.message_end_time)
            stats, pack = self.channel_stats, _MCAP_MESSAGE.pack
            offset = None
            for connection, data in batch:
                if offset is None:   # a chunk's first message of the batch
                    chunk = self.chunk
                    chunk.message_start_time = min(timestamp, chunk.message_start_time)
                    chunk.message_end_time = max(timestamp, chunk.message_end_time)
                    msgs, bio = chunk.msgs, chunk.bio
                    offset = bio.tell()
                cid = connection.id
                stats[cid] += 1
                msgs[cid].append((timestamp, offset))
                bio.write(pack(0x05, 22 + len(data), cid, 0, timestamp, timestamp))
                bio.write(data)
                offset += 31 + len(data)
                if offset > 2**20:
                    self.close_chunk()
                    offset = None

        def close_chunk(self) -> None:
            # rosbags' own, with each channel's message index packed in one call instead
            # of two calls per message.
            chunk = self.chunk
            rec = BytesIO()
            write_uint64(rec, chunk.message_start_time)
            write_uint64(rec, chunk.message_end_time)
            write_uint64(rec, chunk.bio.tell())
            write_uint32(rec, 0)
            compressed = self.compressor(chunk.bio.getvalue())
            write_string(rec, self.compression)
            write_uint64(rec, len(compressed))
            rec.write(compressed)
            chunk_start = self.bio.tell()
            write_record(self.bio, 0x06, rec)
            chunk_end = self.bio.tell()
            offsets: list[tuple[int, int]] = []
            for cid, msgs in chunk.msgs.items():
                offsets.append((cid, self.bio.tell()))
                flat = [number for message in msgs for number in message]
                self.bio.write(struct.pack(f'<BQHI{len(flat)}Q', 0x07, 6 + 16 * len(msgs),
                                           cid, 16 * len(msgs), *flat))
            rec = BytesIO()
            write_uint64(rec, chunk.message_start_time)
            write_uint64(rec, chunk.message_end_time)
            write_uint64(rec, chunk_start)
            write_uint64(rec, chunk_end - chunk_start)
            write_uint32(rec, len(offsets) * 10)
            for cid, offset in offsets:
                write_uint16(rec, cid)
                write_uint64(rec, offset)
            write_uint64(rec, self.bio.tell() - chunk_end)
            write_string(rec, self.compression)
            write_uint64(rec, len(compressed))
            write_uint64(rec, chunk.bio.tell())
            self.chunks.append(rec)
            self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))

    class _Writer(Writer):
        STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _Mcap}

        def add_connection(self, topic: str, msgtype: str, *, msgdef: str, rihs01: str,
                           offered_qos_profiles: Any = (), **_: Any) -> Any:
            if not self.storage:
                raise WriterError('Bag was not opened.')
            if any(c.topic == topic for c in self.connections):
                raise WriterError(f'Connection can only be added once: {topic}.')
            profiles = list(offered_qos_profiles)
            connection = Connection(
                id=len(self.connections) + 1, topic=topic, msgtype=msgtype,
                msgdef=MessageDefinition(MessageDefinitionFormat.MSG, msgdef), digest=rihs01,
                msgcount=0, ext=ConnectionExtRosbag2(serialization_format='cdr',
                                                     offered_qos_profiles=profiles),
                owner=self)
            if msgtype not in self.added_types:
                self.storage.add_msgtype(connection)
                self.added_types.add(msgtype)
            self.storage.add_connection(connection, _qos_yaml(tuple(profiles)))
            self.connections.append(connection)
            self.counts[connection.id] = 0
            return connection

        def write_many(self, timestamp: int, batch: list[tuple[Any, bytes]]) -> None:
            """:meth:`write` of each ``(connection, data)``, all at ``timestamp``."""
            if not isinstance(self.storage, _Mcap):
                for connection, data in batch:
                    self.write(connection, timestamp, data)
                return
            self.storage.write_many(timestamp, batch)
            counts = self.counts
            for connection, _ in batch:
                counts[connection.id] += 1
            if timestamp < self.min_timestamp:
                self.min_timestamp = timestamp
            if timestamp > self.max_timestamp:
                self.max_timestamp = timestamp

        def write(self, connection: Any, timestamp: int, data: bytes) -> None:
            # The connections are this writer's own: no search of the list for them.
            self.storage.write(connection, timestamp, data)
            self.counts[connection.id] += 1
            if timestamp < self.min_timestamp:
                self.min_timestamp = timestamp
            if timestamp > self.max_timestamp:
                self.max_timestamp = timestamp

        def close(self) -> None:
            assert self.storage
            if (self.compression_mode != CompressionMode.NONE or self.version != 9
                    or self.storage_plugin != StoragePlugin.MCAP
                    or len(self.connections) + 6 > len(_SENTINELS)):
                super().close()
                return
            name = self.storage.path.name
            if not _PLAIN_FILE.fullmatch(name):   # a name YAML might quote
                super().close()
                return
            duration = max(0, self.max_timestamp - self.min_timestamp)
            start = self.min_timestamp
            count = sum(self.counts.values())
            numbers = [duration, start, count, *(self.counts[c.id] for c in self.connections),
                       start, duration, count]
            layout = tuple((c.topic, c.msgtype, tuple(c.ext.offered_qos_profiles), c.digest)
                           for c in self.connections)
            whole, inner = _metadata_layout(layout, bool(self.custom_data) and
                                            tuple(self.custom_data.items()))
            self.storage.close(self.version, _fill(inner, numbers, name).strip())
            self.storage = None
            tmp = self.metapath.with_suffix('.yaml.tmp')
            tmp.write_text(_fill(whole, numbers, name), 'utf8')
            tmp.replace(self.metapath)

    @functools.cache
    def _metadata_layout(layout: tuple[Any, ...], custom: Any) -> tuple[list[str], list[str]]:
        """metadata.yaml of a bag of these connections, split at its numbers and file name
        (the whole file, and its inner mapping as the MCAP file embeds it)."""
        n = len(layout)
        s = _SENTINELS
        info = {
            'version': 9, 'storage_identifier': 'mcap', 'relative_file_paths': [_SENTINEL_FILE],
            'duration': {'nanoseconds': s[0]}, 'starting_time': {'nanoseconds_since_epoch': s[1]},
            'message_count': s[2],
            'topics_with_message_count': [
                {'topic_metadata': {'name': topic, 'type': msgtype,
                                    'serialization_format': 'cdr',
                                    'offered_qos_profiles': dump_qos_v9(list(profiles)),
                                    'type_description_hash': digest},
                 'message_count': s[3 + i]}
                for i, (topic, msgtype, profiles, digest) in enumerate(layout)],
            'compression_format': '', 'compression_mode': '',
            'files': [{'path': _SENTINEL_FILE, 'starting_time': {
                'nanoseconds_since_epoch': s[3 + n]}, 'duration': {'nanoseconds': s[4 + n]},
                'message_count': s[5 + n]}],
            'custom_data': dict(custom) if custom else None,
            'ros_distro': 'rosbags',
        }
        return (_split(_dump_yaml({'rosbag2_bagfile_information': info})),
                _split(_dump_yaml(info)))

    return _Writer


_PIECES = re.compile('|'.join([re.escape(_SENTINEL_FILE), *map(str, _SENTINELS)]))


def _split(text: str) -> list[str]:
    """``text`` as [text, marker, text, marker, ..., text]; a marker is a sentinel's index
    (as a string) or '' for the file name."""
    out, last = [], 0
    for match in _PIECES.finditer(text):
        marker = match.group()
        out += [text[last:match.start()],
                '' if marker == _SENTINEL_FILE else str(_SENTINELS.index(int(marker)))]
        last = match.end()
    return [*out, text[last:]]


def _fill(pieces: list[str], numbers: list[int], name: str) -> str:
    out = [pieces[0]]
    for i in range(1, len(pieces), 2):
        marker = pieces[i]
        out += [str(numbers[int(marker)]) if marker else name, pieces[i + 1]]
    return ''.join(out)


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
