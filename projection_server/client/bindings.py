"""Decoding and printing of query bindings (their JSON encoding:
docs/reference/binding_encoding.md).

>>> decode_solution('{"X": {"functor": "f", "args": ["a", {"var": "Y"}]}}')
{'X': Compound('f', (Atom('a'), Var('Y')))}
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
import json
import math
import re
from typing import Any

__all__ = [
    'Atom',
    'Blob',
    'Compound',
    'DecodeError',
    'PrologDict',
    'Var',
    'decode',
    'decode_solution',
    'to_prolog_text',
]


class DecodeError(ValueError):
    """A value that is not in the binding encoding."""


class Atom(str):
    """A Prolog atom (a plain ``str`` is a Prolog string)."""

    def __repr__(self) -> str:
        return f'Atom({str.__repr__(self)})'


@dataclass(frozen=True)
class Var:
    """An unbound variable; equal names in one solution are the same variable."""

    name: str


@dataclass(frozen=True)
class Compound:
    """A compound term ``name(args...)``."""

    name: str
    args: tuple

    def __repr__(self) -> str:
        return f'Compound({self.name!r}, {self.args!r})'


@dataclass(frozen=True)
class PrologDict:
    """A SWI-Prolog dict ``Tag{Key: Value, ...}``."""

    tag: Any
    pairs: tuple


@dataclass(frozen=True)
class Blob:
    """An opaque Prolog object (stream, clause reference, ...), by its printed form."""

    text: str
    type: str


_SPECIAL_FLOATS = {'inf': math.inf, '-inf': -math.inf, 'nan': math.nan}


def decode(value: Any) -> Any:
    """Turn one encoded JSON value (already parsed by :mod:`json`) into Python."""
    if isinstance(value, bool) or value is None:
        raise DecodeError(f'not in the binding encoding: {value!r}')
    if isinstance(value, str):
        return Atom(value)
    if isinstance(value, (int, float)):
        return value
    if isinstance(value, list):
        return [decode(v) for v in value]
    if isinstance(value, dict):
        if 'string' in value:
            return str(value['string'])
        if 'functor' in value:
            return Compound(value['functor'], tuple(decode(a) for a in value['args']))
        if 'var' in value:
            return Var(value['var'])
        if 'float' in value:
            return _SPECIAL_FLOATS[value['float']]
        if 'rational' in value:
            return Fraction(value['rational'].replace('r', '/'))
        if 'dict' in value:
            return PrologDict(decode(value['tag']),
                              tuple((decode(k), decode(v)) for k, v in value['dict']))
        if 'blob' in value:
            return Blob(value['blob'], value['type'])
    raise DecodeError(f'not in the binding encoding: {value!r}')


def decode_solution(text: str) -> dict[str, Any]:
    """Decode one solution (a JSON object text) into ``{variable: value}``."""
    return {name: decode(v) for name, v in json.loads(text).items()}


_PLAIN_ATOM = re.compile(r'^[a-z][a-zA-Z0-9_]*$')
_SYMBOL_ATOM = re.compile(r'^[#$&*+\-./:<=>?@^~\\]+$')


def to_prolog_text(value: Any) -> str:
    """Write a decoded value back in Prolog syntax (for display)."""
    if isinstance(value, Atom):
        s = str(value)
        if _PLAIN_ATOM.match(s) or _SYMBOL_ATOM.match(s) or s in ('[]', '!', ';', '{}'):
            return s
        return "'" + s.replace('\\', '\\\\').replace("'", "\\'") + "'"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, float):
        if math.isnan(value):
            return 'nan'
        if math.isinf(value):
            return 'inf' if value > 0 else '-inf'
        return repr(value)
    if isinstance(value, Fraction):
        return f'{value.numerator}r{value.denominator}'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, list):
        return '[' + ', '.join(to_prolog_text(v) for v in value) + ']'
    if isinstance(value, Var):
        return value.name
    if isinstance(value, Compound):
        if value.name == '[|]' and len(value.args) == 2:
            return f'[{to_prolog_text(value.args[0])}|{to_prolog_text(value.args[1])}]'
        return (to_prolog_text(Atom(value.name)) + '('
                + ', '.join(to_prolog_text(a) for a in value.args) + ')')
    if isinstance(value, PrologDict):
        return (to_prolog_text(value.tag) + '{'
                + ', '.join(f'{to_prolog_text(k)}: {to_prolog_text(v)}' for k, v in value.pairs)
                + '}')
    if isinstance(value, Blob):
        return value.text
    return str(value)
