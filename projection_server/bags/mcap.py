"""The quarantine of rosbags' internals: a faster MCAP writer for rosbags 0.11.9.

rosbags' own :class:`~rosbags.rosbag2.Writer` computes, for every bag, what is the same for
every bag of a layout (each topic's QoS as YAML, ``metadata.yaml``), and packs each
message record through a ``BytesIO`` of its own. :func:`writer_class` subclasses it and its
``McapWriter`` to do that once per process and layout, writing the same bytes. That uses
rosbags' private internals (``PendingChunk``, ``write_record``, the writer's attributes),
which may change in any release: it is written against, and used only with, the version
:data:`ROSBAGS_VERSION`. With any other version installed, :func:`writer_class` is rosbags'
own writer (the same bags, slower), and ``test_bags.py``'s pin test fails loudly so that
this module is checked against the new release.
"""

from __future__ import annotations

from collections import defaultdict
import functools
from io import BytesIO, StringIO
from pathlib import Path
import re
import struct
from typing import Any

__all__ = ['ROSBAGS_VERSION', 'writer_class']

ROSBAGS_VERSION = '0.11.9'   # the release whose internals the subclasses below use


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
def writer_class() -> type:
    """rosbags' bag writer, with what it computes with ruamel YAML per connection and at
    close (the topics' QoS, ``metadata.yaml``) computed once per process and topic layout
    (the YAML text is the same, byte for byte); rosbags' own writer under any other
    rosbags than :data:`ROSBAGS_VERSION`."""
    from importlib.metadata import version

    from rosbags.rosbag2 import Writer

    if version('rosbags') != ROSBAGS_VERSION:
        return Writer

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
            self.write_batches([(timestamp, batch)])

        def write_batches(self, batches: list[tuple[int, list[tuple[Any, bytes]]]]) -> None:
            """:meth:`write` of each ``(connection, data)`` of each ``(timestamp, batch)``
            (the timestamps in order), in one loop."""
            if not batches:
                return
            self.message_start_time = min(batches[0][0], self.message_start_time)
            self.message_end_time = max(batches[-1][0], self.message_end_time)
            stats, pack = self.channel_stats, _MCAP_MESSAGE.pack
            offset = None
            for timestamp, batch in batches:
                for connection, data in batch:
                    if offset is None:   # a chunk's first message of the batches
                        chunk = self.chunk
                        chunk.message_start_time = min(timestamp, chunk.message_start_time)
                        msgs, bio = chunk.msgs, chunk.bio
                        offset = bio.tell()
                    cid = connection.id
                    stats[cid] += 1
                    msgs[cid].append((timestamp, offset))
                    bio.write(pack(0x05, 22 + len(data), cid, 0, timestamp, timestamp))
                    bio.write(data)
                    offset += 31 + len(data)
                    if offset > 2**20:
                        chunk.message_end_time = max(timestamp, chunk.message_end_time)
                        self.close_chunk()
                        offset = None
                if offset is not None:
                    chunk.message_end_time = max(timestamp, chunk.message_end_time)

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
            self.write_batches([(timestamp, batch)])

        def write_batches(self, batches: list[tuple[int, list[tuple[Any, bytes]]]]) -> None:
            """:meth:`write` of each ``(connection, data)`` of each ``(timestamp, batch)``,
            the timestamps in order."""
            if not isinstance(self.storage, _Mcap):
                for timestamp, batch in batches:
                    for connection, data in batch:
                        self.write(connection, timestamp, data)
                return
            self.storage.write_batches(batches)
            counts = self.counts
            for _, batch in batches:
                for connection, _ in batch:
                    counts[connection.id] += 1
            if batches:
                self.min_timestamp = min(self.min_timestamp, batches[0][0])
                self.max_timestamp = max(self.max_timestamp, batches[-1][0])

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
