"""Read the exported predicates of ``prolog/*.pl`` and their PlDoc comments.

A module's export list is its ``:- module(Name, [...])`` directive; a predicate's
documentation is the ``%!`` block before its clauses: one or more mode lines
(``%!  make_projection(+Scenario, ...) is nondet.``), then ``%`` lines of prose, with
PlDoc's ``@tag`` lines (``@error``, ``@arg``, ``@see``) at the end.

Used by the documentation's reference (``docs/_ext/projection_reference.py``) and by
``test/test_docs_reference.py``; it imports nothing but the standard library.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import re
import textwrap

__all__ = ['Module', 'Predicate', 'read_module', 'read_modules']

_MODULE = re.compile(r'^:-\s*module\(\s*(\w+)\s*,\s*\[(.*?)\]\s*\)\s*\.', re.S | re.M)
_INDICATOR = re.compile(r'\b([a-z]\w*)\s*(//?)\s*(\d+)')
_TITLE = re.compile(r'/\*\*\s*<module>\s*(.*?)\n(.*?)\*/', re.S)
_MODE_HEAD = re.compile(r'^\s*([a-z]\w*)\s*(\(|\s|$)')
_TAG = re.compile(r'^@(\w+)\s*(.*)$')


@dataclass
class Predicate:
    """One exported predicate: ``name/arity`` and what its PlDoc comment says."""

    name: str
    arity: int
    dcg: bool = False
    modes: list[str] = field(default_factory=list)
    prose: list[str] = field(default_factory=list)
    tags: list[tuple[str, str]] = field(default_factory=list)

    @property
    def indicator(self) -> str:
        return f'{self.name}{"//" if self.dcg else "/"}{self.arity}'

    @property
    def documented(self) -> bool:
        return bool(self.modes)


@dataclass
class Module:
    """A Prolog module of ``prolog/``: its name, title, overview and exports in order."""

    name: str
    path: Path
    title: str
    overview: list[str]
    exports: list[Predicate]


def _arity(head: str) -> int:
    """The number of top-level arguments of the mode line's head ``name(...)``."""
    open_at = head.find('(')
    if open_at < 0:
        return 0
    depth, count, quote = 0, 1, ''
    for ch in head[open_at:]:
        if quote:
            quote = '' if ch == quote else quote
        elif ch in '\'"`':
            quote = ch
        elif ch in '([{':
            depth += 1
        elif ch in ')]}':
            depth -= 1
            if depth == 0:
                break
        elif ch == ',' and depth == 1:
            count += 1
    return count


def _open_brackets(text: str) -> int:
    return sum(text.count(c) for c in '([{') - sum(text.count(c) for c in ')]}')


def _doc_blocks(lines: list[str]):
    """``(modes, body)`` of each ``%!`` comment block of a file's lines."""
    i = 0
    while i < len(lines):
        if not lines[i].startswith('%!'):
            i += 1
            continue
        modes, body = [], []
        while i < len(lines) and lines[i].startswith('%!'):
            text = lines[i][2:].strip()
            if modes and _open_brackets(modes[-1]) > 0:   # a mode line wrapped
                modes[-1] = f'{modes[-1]} {text}'
            else:
                modes.append(text)
            i += 1
        while i < len(lines) and lines[i].startswith('%') and not lines[i].startswith('%!'):
            text = lines[i][1:]
            body.append(text[1:] if text.startswith(' ') else text)
            i += 1
        yield modes, body


def _tags(body: list[str]) -> tuple[list[str], list[tuple[str, str]]]:
    prose, tags = [], []
    for line in body:
        m = _TAG.match(line.strip())
        if m:
            tags.append((m.group(1), m.group(2)))
        elif tags and line.strip():
            tags[-1] = (tags[-1][0], f'{tags[-1][1]} {line.strip()}')
        else:
            prose.append(line)
    while prose and not prose[-1].strip():
        prose.pop()
    while prose and not prose[0].strip():
        prose.pop(0)
    return textwrap.dedent('\n'.join(prose)).splitlines(), tags


def read_module(path: Path) -> Module | None:
    """The module of ``path``, or None when the file is not a module."""
    text = path.read_text()
    m = _MODULE.search(text)
    if not m:
        return None
    exports_text = re.sub(r'%.*', '', m.group(2))
    exports = [Predicate(name, int(arity), dcg=(slash == '//'))
               for name, slash, arity in _INDICATOR.findall(exports_text)]
    by_key = {(p.name, p.arity + (2 if p.dcg else 0)): p for p in exports}
    for modes, body in _doc_blocks(text.splitlines()):
        prose, tags = _tags(body)
        for mode in modes:
            head = _MODE_HEAD.match(mode)
            if not head:
                continue
            dcg = '//' in mode.split(' is ')[0][-4:] or re.search(r'\)\s*//', mode) is not None
            key = (head.group(1), _arity(mode) + (2 if dcg else 0))
            p = by_key.get(key)
            if p is not None and mode not in p.modes:
                p.modes.append(mode)
                if not p.prose:
                    p.prose, p.tags = prose, tags
    t = _TITLE.search(text)
    title = t.group(1).strip() if t else m.group(1)
    overview = t.group(2).splitlines() if t else []
    return Module(m.group(1), path, title, overview, exports)


def read_modules(directory: Path) -> list[Module]:
    """Every module of ``directory/*.pl``, by file name."""
    return [m for m in (read_module(p) for p in sorted(directory.glob('*.pl'))) if m]
