"""Sphinx directives that make the reference from the sources, so that it cannot drift.

- ``{prolog-modules}``: every module of ``prolog/``, its exported predicates and their
  PlDoc comments (:mod:`pldoc`); an exported predicate without one is a warning, which
  ``sphinx-build -W`` turns into a failed build.
- ``{ros-interfaces}``: the node's services and action (from ``create_service`` and
  ``ActionServer`` in ``projection_server/service/``), then every ``.srv``, ``.action`` and
  ``.msg`` of ``msg_defs/``, as the files say.
- ``{node-parameters}``: the node's parameters, from
  ``projection_server.service.parameters.PARAMETERS``.
- ``{error-kinds}``: ``projection_server.errors.ErrorKind``, with each kind's comment.
- ``{bag-topics}``: ``projection_server.bags.schema.TOPICS`` with their types and QoS.
"""

from __future__ import annotations

import ast
import io
from pathlib import Path
import re
import sys
import tokenize

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

sys.path.insert(0, str(Path(__file__).parent))
import pldoc  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
logger = logging.getLogger(__name__)


class _MarkdownDirective(SphinxDirective):
    """A directive whose content is Markdown made by :meth:`markdown`."""

    has_content = False

    def markdown(self) -> list[str]:
        raise NotImplementedError

    def sources(self) -> list[Path]:
        return []

    def run(self):
        for path in self.sources():
            self.env.note_dependency(str(path))
        container = nodes.container()
        self.state.nested_parse(StringList(self.markdown()), 0, container, match_titles=True)
        return container.children


def _fence(text: str, lang: str = 'text') -> list[str]:
    ticks = '````' if '```' in text else '```'
    return [f'{ticks}{lang}', *text.rstrip('\n').splitlines(), ticks, '']


def _cell(text: str) -> str:
    return text.replace('|', '\\|').replace('\n', ' ')


class PrologModules(_MarkdownDirective):
    """Every module of ``prolog/`` with its exported predicates."""

    def sources(self):
        return sorted((ROOT / 'prolog').glob('*.pl'))

    def markdown(self):
        out = []
        for module in pldoc.read_modules(ROOT / 'prolog'):
            rel = module.path.relative_to(ROOT)
            out += [f'(prolog-{module.name})=', f'## `{module.name}`: {module.title}', '',
                    f'`{rel}` exports:', '']
            out += [', '.join(f'[`{p.indicator}`](#{_anchor(module, p)})'
                              for p in module.exports), '']
            for p in module.exports:
                out += [f'({_anchor(module, p)})=', f'### `{p.indicator}`', '']
                if not p.documented:
                    logger.warning(f'{rel}: {p.indicator} is exported without a PlDoc '
                                   f'comment (%!)', location=(self.env.docname, self.lineno))
                    continue
                out += _fence('\n'.join(p.modes))
                out += [*_pldoc_prose(p.prose), '']
                for tag, text in p.tags:
                    label = {'error': 'Error', 'arg': 'Argument', 'see': 'See',
                             'throws': 'Throws'}.get(tag, tag.capitalize())
                    out += [f'- **{label}:** {_inline(text)}']
                out += ['']
        return out


def _anchor(module: pldoc.Module, p: pldoc.Predicate) -> str:
    return f'pred-{module.name}-{p.name}-{p.arity}'.replace('_', '-').lower()


def _inline(text: str) -> str:
    """A tag's text, with the term it begins with as code."""
    m = re.match(r'^(\S+\(.*?\)|\S+)(\s.*)?$', text)
    if not m or '`' in text:
        return text
    return f'`{m.group(1)}`{m.group(2) or ""}'


def _pldoc_prose(lines: list[str]) -> list[str]:
    """PlDoc's prose as Markdown: its indented code and ``==``-fenced code fenced."""
    out, in_code = [], False
    for line in lines:
        if line.strip() == '==':
            out.append('```text' if not in_code else '```')
            in_code = not in_code
        elif line.strip().startswith('```'):
            out.append('```text' if not in_code else '```')
            in_code = not in_code
        else:
            out.append(line)
    if in_code:
        out.append('```')
    return out


class RosInterfaces(_MarkdownDirective):
    """The node's services and action, then every interface file of ``msg_defs/``."""

    def sources(self):
        return sorted((ROOT / 'msg_defs').glob('*/*.*')) + [
            ROOT / 'projection_server/service/node.py',
            ROOT / 'projection_server/service/project_action.py']

    def markdown(self):
        service_dir = ROOT / 'projection_server/service'
        endpoints = []
        for path in (service_dir / 'node.py', service_dir / 'project_action.py'):
            text = path.read_text()
            endpoints += [('service', t, n) for t, n in
                          re.findall(r"create_service\(\s*(\w+),\s*'([^']+)'", text)]
            endpoints += [('action', t, n) for t, n in
                          re.findall(r"ActionServer\(\s*\w+,\s*(\w+),\s*'([^']+)'", text)]
        out = ['## The node\'s services and action', '',
               'Names are relative to the node (`/projection_server/...` by default).', '',
               '| name | kind | type |', '|---|---|---|']
        for kind, type_name, name in endpoints:
            full = _interface_name(type_name)
            link = f'[`{full}`](#{_iface_anchor(full)})' if full.startswith(
                'projection_interfaces') else f'`{full}`'
            out.append(f'| `{name}` | {kind} | {link} |')
        out.append('')
        for folder, title in (('srv', 'Services'), ('action', 'Action'), ('msg', 'Messages')):
            out += [f'## {title}', '']
            for path in sorted((ROOT / 'msg_defs' / folder).glob('*')):
                full = f'projection_interfaces/{folder}/{path.stem}'
                out += [f'({_iface_anchor(full)})=', f'### `{full}`', '',
                        f'`msg_defs/{folder}/{path.name}`:', '']
                out += _fence(path.read_text())
        return out


def _interface_name(type_name: str) -> str:
    ours = {p.stem: f'projection_interfaces/{p.parent.name}/{p.stem}'
            for p in (ROOT / 'msg_defs').glob('*/*.*') if p.suffix in ('.msg', '.srv', '.action')}
    return ours.get(type_name, {'Trigger': 'std_srvs/srv/Trigger'}.get(type_name, type_name))


def _iface_anchor(full: str) -> str:
    return 'iface-' + full.replace('/', '-').replace('_', '-').lower()


class NodeParameters(_MarkdownDirective):
    """The node's parameters, from their descriptors' table."""

    def sources(self):
        return [ROOT / 'projection_server/service/parameters.py']

    def markdown(self):
        from projection_server.service.parameters import PARAMETERS

        out = ['| parameter | type | default | range | read-only | what it is |',
               '|---|---|---|---|---|---|']
        for spec in PARAMETERS:
            kind = {bool: 'bool', int: 'integer', float: 'double', str: 'string',
                    list: 'string array'}[type(spec.default)]
            default = {True: 'true', False: 'false'}.get(spec.default, spec.default) if \
                isinstance(spec.default, bool) else spec.default
            default = f'`{default!r}`' if isinstance(default, str) and default == '' else \
                f'`{default}`' if default != [] else '`[]`'
            rng = f'{spec.range[0]} to {spec.range[1]}' if spec.range else spec.constraints
            out.append(f'| `{spec.name}` | {kind} | {default} | {_cell(str(rng))} | '
                       f'{"yes" if spec.read_only else "no"} | {_cell(spec.description)} |')
        return out + ['']


class ErrorKinds(_MarkdownDirective):
    """The kinds of :class:`projection_server.errors.ErrorKind`, with their comments."""

    def sources(self):
        return [ROOT / 'projection_server/errors.py']

    def markdown(self):
        path = ROOT / 'projection_server/errors.py'
        text = path.read_text()
        comments = {}
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type == tokenize.COMMENT:
                comments[tok.start[0]] = tok.string.lstrip('# ')
        cls = next(n for n in ast.parse(text).body
                   if isinstance(n, ast.ClassDef) and n.name == 'ErrorKind')
        out = ['| kind | when |', '|---|---|']
        for item in cls.body:
            if isinstance(item, ast.Assign) and isinstance(item.value, ast.Constant):
                out.append(f'| `{item.value.value}` | '
                           f'{_cell(comments.get(item.lineno, ""))} |')
        return out + ['']


class BagTopics(_MarkdownDirective):
    """The topics of a projection's bag, their message types and QoS."""

    def sources(self):
        return [ROOT / 'projection_server/bags/schema.py']

    def markdown(self):
        from projection_server.bags.schema import is_latched, TOPIC_TYPES, TOPICS

        out = ['| topic | type | QoS | what it carries |', '|---|---|---|---|']
        for key, topic in TOPICS.items():
            msgtype, what = TOPIC_TYPES[key]
            qos = ('reliable, transient local, depth 1' if is_latched(topic)
                   else 'reliable, volatile, depth 100')
            out.append(f'| `{topic}` | `{msgtype}` | {qos} | {_cell(what)} |')
        return out + ['']


def setup(app):
    app.add_directive('prolog-modules', PrologModules)
    app.add_directive('ros-interfaces', RosInterfaces)
    app.add_directive('node-parameters', NodeParameters)
    app.add_directive('error-kinds', ErrorKinds)
    app.add_directive('bag-topics', BagTopics)
    return {'version': '1', 'parallel_read_safe': True, 'parallel_write_safe': True}
