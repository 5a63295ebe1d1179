"""CDR serialization of messages whose layout does not change from one sample to the next:
:class:`CdrTemplate`, and each message type's definition and hash as a bag records them."""

from __future__ import annotations

import copy
from fnmatch import fnmatchcase
import functools
import struct
from typing import Any, Callable, TYPE_CHECKING

import numpy as np

from projection_server.bags.schema import typestore

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = ['CdrTemplate', 'definition']


class CdrTemplate:
    """Serializes messages that differ from a prototype only in some of their numbers.

    ``variable`` are patterns (:func:`fnmatch.fnmatchcase`) of the dotted paths of the
    numeric fields that vary, with sequence elements as indices (``transforms.0.header.
    stamp.sec``; ``transforms.*.transform.*`` matches every number of every transform's
    pose). Strings and sequence lengths are those of the prototype, and so are the numbers
    no pattern matches. :meth:`pack` takes the varying numbers in the order of the message
    definition and returns the CDR bytes (little endian, with its encapsulation header)
    that rosbags' ``serialize_cdr`` gives of the message with those numbers: the message is
    one ``struct`` format of constant byte runs and numbers. :meth:`pack_rows` packs many
    messages at once, from an array of their numbers.
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
        offset = 0
        fields: list[tuple[int, str]] = []   # each number's (byte offset, struct code)
        for kind, value in [*self._tokens, ('end', None)]:
            if kind == 'c':
                run.append(value)
                offset += len(value)
                continue
            if kind == 'v':
                fields.append((offset, value))
                offset += struct.calcsize('<' + value)
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
        self._base = np.frombuffer(self.pack([0] * count), dtype=np.uint8)
        self._runs = _runs(fields)
        del self._tokens

    def pack_rows(self, values: np.ndarray) -> bytes:
        """The messages of each row of ``values`` (n x :attr:`count`: each row the numbers
        :meth:`pack` takes), one after the other: n x :attr:`size` bytes, each message the
        bytes :meth:`pack` gives of its row (an integer field takes its row's value, which
        must be a whole number; numpy writes the same little-endian IEEE and two's-complement
        bytes as ``struct``)."""
        n = len(values)
        out = np.tile(self._base, (n, 1))
        for offset, dtype, first, width in self._runs:
            end = offset + dtype.itemsize * width
            out[:, offset:end].view(dtype)[:] = values[:, first:first + width]
        return out.tobytes()

    def __deepcopy__(self, memo: dict[int, Any]) -> CdrTemplate:
        return self   # it does not change once made: a copied monitor shares its templates

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


def _runs(fields: list[tuple[int, str]]) -> list[tuple[int, np.dtype, int, int]]:
    """The numbers of a message as runs of adjacent ones of one type: ``(byte offset,
    dtype, index of the first, how many)`` each."""
    runs: list[list[Any]] = []
    for index, (offset, code) in enumerate(fields):
        dtype = np.dtype('<' + code)
        last = runs[-1] if runs else None
        if (last is not None and last[1] == dtype
                and last[0] + dtype.itemsize * last[3] == offset):
            last[3] += 1
        else:
            runs.append([offset, dtype, index, 1])
    return [tuple(run) for run in runs]


# Base type -> (struct code, size); the strings are handled apart.
_CDR_NUMBERS = {
    'bool': ('?', 1), 'byte': ('B', 1), 'char': ('B', 1), 'int8': ('b', 1),
    'uint8': ('B', 1), 'int16': ('h', 2), 'uint16': ('H', 2), 'int32': ('i', 4),
    'uint32': ('I', 4), 'int64': ('q', 8), 'uint64': ('Q', 8), 'float32': ('f', 4),
    'float64': ('d', 8),
}


@functools.cache
def definition(msgtype: str) -> tuple[str, str]:
    """``(message definition, RIHS01 hash)`` of ``msgtype``, as a bag's connection has it."""
    store = typestore()
    return store.generate_msgdef(msgtype, ros_version=2)[0], store.hash_rihs01(msgtype)
