"""Every ``ros2 service call`` / ``ros2 action send_goal`` line of the README and of the
documentation site (``docs/``) does what its page says, with the request built from its
YAML text the way the ROS 2 command line does.

The command line loads the YAML and sets each field by name, converting the value with the
Python type of the field: ``int(v)``, ``float(v)``, ``str(v)``, ``bytes(v)`` (so a ``byte``
field given ``2`` gets ``bytes(2)``, two zero bytes: why ``mode`` is a ``uint8``), arrays
element by element, nested messages field by field. :func:`request_from_yaml` follows those
rules from the field types the message declares.
"""

from __future__ import annotations

import array
import json
from pathlib import Path
import shlex

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
STANDIN = '/standin_robot'   # the stand-in robot's node: its examples are its own test's


def pages() -> list[Path]:
    """The README and the site's Markdown pages."""
    return [README] + sorted(p for p in (ROOT / 'docs').rglob('*.md')
                             if '_build' not in p.parts and p.name != 'contracts.md')
_INTEGERS = {'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64'}


def request_from_yaml(msg_type, text: str):
    """A ``msg_type`` instance with the fields of the YAML mapping ``text``."""
    values = yaml.safe_load(text) if text.strip() else {}
    msg = msg_type()
    _set_fields(msg, values or {})
    return msg


def _set_fields(msg, values: dict) -> None:
    if not isinstance(values, dict):
        raise TypeError(f'{values!r} is not a mapping of field names to values')
    types = msg.get_fields_and_field_types()
    for name, value in values.items():
        if name not in types:
            raise AttributeError(f'{type(msg).__name__} has no field {name!r}')
        setattr(msg, name, _convert(getattr(msg, name), types[name], value))


def _convert(current, field_type: str, value):
    if field_type in _INTEGERS:
        return int(value)
    if field_type in ('float', 'double'):
        return float(value)
    if field_type in ('string', 'wstring'):
        return str(value)
    if field_type == 'boolean':
        return bool(value)
    if field_type == 'octet':
        return bytes(value)          # the CLI's rule for byte: bytes(2) == b'\x00\x00'
    if isinstance(current, array.array):
        return array.array(current.typecode, value)
    if isinstance(current, (bytes, list)) and field_type.startswith('sequence<'):
        element = field_type[len('sequence<'):].split(',')[0].rstrip('>')
        if element in ('octet', 'uint8') and isinstance(current, bytes):
            return bytes(value)
        return [_convert(None, element, v) for v in value]
    nested = type(current)()       # a message field: set its fields by name
    _set_fields(nested, value)
    return nested


def readme_commands(paths: list[Path] | None = None) -> list[tuple[str, str, str, str]]:
    """(verb, name, type, yaml) of each ``ros2 service call`` / ``ros2 action send_goal``
    line of the pages (by default the README and the site's), continuation lines joined,
    each command once."""
    text = '\n'.join(p.read_text() for p in (paths or pages())).replace('\\\n', ' ')
    out = []
    for line in text.splitlines():
        line = line.strip()
        if not line.startswith(('ros2 service call ', 'ros2 action send_goal ')):
            continue
        words = shlex.split(line, comments=True)
        verb = ' '.join(words[:3])
        args = [w for w in words[3:] if not w.startswith('-')]
        command = (verb, args[0], args[1], args[2] if len(args) > 2 else '')
        if command not in out:
            out.append(command)
    return out


def test_the_conversion_follows_the_cli_type_rules():
    from builtin_interfaces.msg import Time
    from projection_interfaces.srv import PrologQuery
    from std_msgs.msg import Header

    r = request_from_yaml(PrologQuery.Request,
                          "{mode: 2, query: 'X = 1', timeout: 3, max_solutions: 4}")
    assert (r.mode, r.query, r.timeout, r.max_solutions) == (2, 'X = 1', 3.0, 4)
    h = request_from_yaml(Header, "{frame_id: 7, stamp: {sec: 1, nanosec: 2}}")
    assert (h.frame_id, h.stamp) == ('7', Time(sec=1, nanosec=2))
    with pytest.raises(AttributeError):
        request_from_yaml(PrologQuery.Request, '{mood: 2}')
    # What the command line does to a byte field, and so did to rosprolog's byte mode.
    assert _convert(b'\x00', 'octet', 2) == b'\x00\x00'


def test_the_readme_shows_each_service_and_the_action():
    names = {(verb, name.rsplit('/', 1)[-1]) for verb, name, _, _ in readme_commands([README])}
    assert {('ros2 service call', 'query'), ('ros2 service call', 'next_solution'),
            ('ros2 service call', 'finish'), ('ros2 action send_goal', 'project')} <= names


def _sol(r) -> list[dict]:
    return [json.loads(s) for s in r.solutions]


# What the README says each example does, keyed by its YAML text.
def _once(r, _):
    assert r.ok and _sol(r) == [{'X': 'a'}], r


def _capped(r, _):
    assert r.ok and _sol(r) == [{'X': 1}, {'X': 2}, {'X': 3}] and r.truncated, r


def _opened(r, _):
    assert r.ok and r.id == 'me/1' and r.solutions == [], r


def _next(r, types):
    assert r.status == types['next'].Response.OK and json.loads(r.solution) == {'X': 1}, r


def _finished(r, _):
    assert r.ok and r.closed == 1, r


def _projected(r, _):
    assert r.ok and sorted(s['F'] for s in _sol(r)) == [5], r


DOCUMENTED = {
    "{mode: 2, query: 'member(X, [a, b])'}": _once,
    "{mode: 0, query: 'between(1, 10, X)', max_solutions: 3}": _capped,
    "{mode: 1, id: 'me/1', query: 'between(1, inf, X)'}": _opened,
    "{id: 'me/1'}": _next,
    "{id: 'me/*'}": _finished,
    "{mode: 0, query: 'make_projection(grasping, grasp_object, [(F, force, [1, 5, 11])], T),"
    " not(occurs(break, _, T)), not(occurs(slip, _, T))', timeout: 120}": _projected,
    "{mode: 0, query: 'make_projection(grasping, plan([move_to(egg1, [-0.09, 0, 0],"
    " [orientation(side(0)), speed(2.0)]), move_to(egg1, [0, 0, 0],"
    " [speed(0.15)]), close_gripper(F), wait(0.3), move_by([0, 0, 0.1]), wait(1.0)]),"
    " [(F, force, [1, 5, 11])], T), not(occurs(break, _, T)), not(occurs(slip, _, T))',"
    " timeout: 120}": _projected,
}


def test_every_example_does_what_its_page_says(server, call, node):
    import rclpy
    from rclpy.action import ActionClient

    from projection_server.client.discovery import handshake
    from projection_interfaces.action import Project
    from projection_interfaces.srv import PrologFinish, PrologNextSolution, PrologQuery

    types = {'projection_interfaces/srv/PrologQuery': ('query', PrologQuery),
             'projection_interfaces/srv/PrologNextSolution': ('next_solution',
                                                              PrologNextSolution),
             'projection_interfaces/srv/PrologFinish': ('finish', PrologFinish)}
    # The stand-in robot's examples run against the stand-in (test_standin_robot).
    commands = [c for c in readme_commands() if not c[1].startswith(STANDIN + '/')]
    assert commands, 'no ros2 examples found in the README or docs/'
    for verb, name, type_name, text in commands:
        assert name.startswith(server + '/'), name
        if verb == 'ros2 action send_goal':
            assert type_name == 'projection_interfaces/action/Project'
            goal = request_from_yaml(Project.Goal, text)
            client = ActionClient(node, Project, name)
            assert client.wait_for_server(timeout_sec=20.0) and handshake(node, server, 20.0)
            sent = client.send_goal_async(goal)
            rclpy.spin_until_future_complete(node, sent, timeout_sec=30.0)
            done = sent.result().get_result_async()
            rclpy.spin_until_future_complete(node, done, timeout_sec=120.0)
            check = DOCUMENTED.get(text)
            assert check is not None, f'no documented behaviour for the README example {text}'
            check(done.result().result, None)
            client.destroy()
            continue
        service, srv_type = types[type_name]
        assert name == f'{server}/{service}'
        check = DOCUMENTED.get(text)
        assert check is not None, f'no documented behaviour for the README example {text}'
        response = call(srv_type, service, request_from_yaml(srv_type.Request, text))
        check(response, {'next': PrologNextSolution})
