"""The documentation site builds without a warning, and its reference covers what the
sources define: every exported predicate has a PlDoc comment, every parameter, interface,
error kind and bag topic is on its page, and a bag's topics are what a projection writes."""

from __future__ import annotations

import html
from pathlib import Path
import re
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'docs' / '_ext'))
import pldoc  # noqa: E402


@pytest.fixture(scope='module')
def site(tmp_path_factory) -> Path:
    """The site built as ``make docs`` builds it (warnings are errors), into a tmp dir."""
    out = tmp_path_factory.mktemp('site')
    run = subprocess.run(
        [sys.executable, '-m', 'sphinx', '-W', '--keep-going', '-q', '-b', 'html',
         '-d', str(out / 'doctrees'), str(ROOT / 'docs'), str(out / 'html')],
        capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert not run.stderr.strip(), run.stderr
    return out / 'html'


def text_of(page: Path) -> str:
    return html.unescape(re.sub(r'<[^>]+>', ' ', page.read_text()))


def test_every_exported_predicate_has_a_pldoc_comment():
    modules = pldoc.read_modules(ROOT / 'prolog')
    assert len(modules) >= 10
    missing = [f'{m.path.name}: {p.indicator}' for m in modules for p in m.exports
               if not p.documented]
    assert not missing, f'exported without a %! comment: {missing}'


def test_the_pldoc_reader_sees_a_predicate_without_a_comment(tmp_path):
    (tmp_path / 'm.pl').write_text(
        ':- module(m, [ a/1,   % +X\n                b/2 ]).\n\n'
        '%!  a(+X) is det.\n%\n%   Says X.\n%\n%   @error type_error(integer, X)\n'
        'a(_).\n\n% b(X, Y): not PlDoc.\nb(_, _).\n')
    (module,) = pldoc.read_modules(tmp_path)
    a, b = module.exports
    assert (a.indicator, a.documented, a.modes) == ('a/1', True, ['a(+X) is det.'])
    assert a.prose == ['Says X.'] and a.tags == [('error', 'type_error(integer, X)')]
    assert (b.indicator, b.documented) == ('b/2', False)


def test_the_site_builds_without_warnings_and_documents_every_predicate(site):
    page = text_of(site / 'reference' / 'predicates.html')
    for module in pldoc.read_modules(ROOT / 'prolog'):
        for p in module.exports:
            assert p.indicator in page, p.indicator
            assert p.modes[0].split('(')[0] in page


def test_the_reference_lists_every_parameter_with_its_range(site):
    from projection_server.service.parameters import PARAMETERS
    page = text_of(site / 'reference' / 'parameters.html')
    for spec in PARAMETERS:
        assert spec.name in page and spec.description in page, spec.name
        if spec.range:
            assert f'{spec.range[0]} to {spec.range[1]}' in page, spec.name


def test_the_reference_shows_every_interface_and_endpoint(site):
    page = text_of(site / 'reference' / 'interfaces.html')
    for path in sorted((ROOT / 'msg_defs').glob('*/*.*')):
        if path.suffix in ('.msg', '.srv', '.action'):
            assert f'projection_interfaces/{path.parent.name}/{path.stem}' in page, path
            first_field = next(line for line in path.read_text().splitlines()
                               if line and not line.startswith('#'))
            assert first_field in page, (path, first_field)
    for endpoint in ('~/query', '~/next_solution', '~/finish', '~/ping', '~/project'):
        assert endpoint in page, endpoint


def test_the_reference_lists_every_error_kind(site):
    from projection_server.errors import ErrorKind
    page = text_of(site / 'reference' / 'errors.html')
    for kind in ErrorKind:
        assert str(kind) in page, kind


def test_the_reference_lists_every_bag_topic_with_its_type(site):
    from projection_server.bags.schema import TOPIC_TYPES, TOPICS
    assert set(TOPIC_TYPES) == set(TOPICS)
    page = text_of(site / 'reference' / 'bag.html')
    for key, topic in TOPICS.items():
        assert topic in page and TOPIC_TYPES[key][0] in page, topic


def test_the_python_client_is_documented_from_its_docstrings(site):
    page = text_of(site / 'reference' / 'python_client.html')
    from projection_server.client import __all__ as names
    for name in names:
        assert name in page, name
    assert 'The first solution, or None if the query has none.' in page


def test_the_site_has_no_dated_notes():
    dated = re.compile(r'\b20\d\d-\d\d-\d\d\b|\b[Ss]ince \d|\buntil \d\d:\d\d')
    pages = [ROOT / 'README.md'] + [p for p in (ROOT / 'docs').rglob('*.md')
                                    if '_build' not in p.parts and p.name != 'contracts.md']
    found = [f'{p.relative_to(ROOT)}: {m.group(0)}' for p in pages
             for m in dated.finditer(p.read_text())]
    assert not found, found


def test_the_bag_topics_are_those_a_projection_writes(call):
    """The table the reference is made from against the connections of a real bag."""
    import json

    from projection_interfaces.srv import PrologQuery
    from rosbags.rosbag2 import Reader

    from projection_server.bags.schema import TOPIC_TYPES, TOPICS
    Q = PrologQuery.Request
    r = call(PrologQuery, 'query', Q(mode=Q.ONCE, timeout=120.0, query='''
        create_scenario(S), add_to_scenario(S, [kitchen_env, panda_robot, egg1]),
        make_projection(S, plan([move_to(egg1, [0, 0, 0.10], [orientation(top), speed(0.5)]),
                                 close_gripper(5)]), [], TL),
        timeline_property(TL, meta(Meta)), get_dict(bag, Meta, Bag)'''), timeout=240.0)
    assert r.ok, r.message
    bag = json.loads(r.solutions[0])['Bag']
    bag = bag['string'] if isinstance(bag, dict) else bag
    with Reader(bag) as reader:
        written = {c.topic: c.msgtype for c in reader.connections}
    expected = {TOPICS[k]: t for k, (t, _) in TOPIC_TYPES.items()}
    for topic, msgtype in written.items():
        assert expected.get(topic) == msgtype, (topic, msgtype)
    # a grasp writes every topic but the batter's
    assert set(expected) - set(written) == {TOPICS['batter'], TOPICS['bonds']}, written
