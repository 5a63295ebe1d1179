"""Every Python block of the README and the site runs, and does what its comments say.

A block runs as a script of its own (it calls ``rclpy.init()`` itself), as a user would
paste it. A line ``expression  # value`` whose comment is a Python value is checked: the
expression must equal it. Three kinds of block, told apart by what they do:

* a client of ``/projection_server``: run against the session's node, whose name it is;
* a script that starts a node of its own (``NodeProcess``): run in a ROS domain of its
  own, so that its node is not the session's; it must end by itself, its node stopped;
* a node spun in the script's own process (``ProjectionServerNode`` and ``spin()``): it
  spins until stopped, so it runs in a domain of its own while the test, a client in that
  domain, waits for its query service and asks it a query; then Ctrl-C must end it.
"""

from __future__ import annotations

import ast
import json
import os
from pathlib import Path
import re
import signal
import subprocess
import sys

import pytest

from test.test_docs_queries import pages, ROOT

_PYTHON = re.compile(r'^```python\n(.*?)^```$', re.M | re.S)
_CHECKED = re.compile(r'^(\s*)(\S.*?)\s+#\s*(\S.*)$')
PREAMBLE = 'from projection_server.client.bindings import Atom, Compound, Var\n'


def blocks() -> list[tuple[str, int, str]]:
    """(page, index on the page, code) of every Python block."""
    found = []
    for page in pages():
        for i, code in enumerate(_PYTHON.findall(page.read_text())):
            found.append((str(page.relative_to(ROOT)), i, code))
    return found


def _is_expression(text: str) -> bool:
    try:
        ast.parse(text, mode='eval')
    except SyntaxError:
        return False
    return True


def checked(code: str) -> tuple[str, int]:
    """The block with each ``expression  # value`` line turned into an assertion, and how
    many lines were turned."""
    lines, n = [], 0
    for line in code.splitlines():
        m = _CHECKED.match(line)
        # (``...  # what goes here`` is a placeholder, not a claim)
        if m and m.group(2) != '...' and _is_expression(m.group(2)) and _is_expression(m.group(3)):
            indent, expr, value = m.groups()
            line = (f'{indent}assert ({expr}) == ({value}), '
                    f'{f"{expr} should be {value}"!r} + f", not {{({expr})!r}}"')
            n += 1
        lines.append(line)
    return PREAMBLE + '\n'.join(lines) + '\n', n


def kind(code: str) -> str:
    if 'NodeProcess(' in code:
        return 'own node'
    if 'ProjectionServerNode(' in code and '.spin()' in code:
        return 'in process'
    return 'client'


def _env(domain: int | None = None) -> dict[str, str]:
    env = dict(os.environ)
    if domain is not None:
        env['ROS_DOMAIN_ID'] = str(domain)
    return env


def _other_domain() -> int:
    return (int(os.environ.get('ROS_DOMAIN_ID', '0')) + 101) % 200 + 10


BLOCKS = blocks()


def test_the_pages_have_python_blocks_of_each_kind():
    kinds = {kind(code) for _, _, code in BLOCKS}
    assert kinds == {'client', 'own node', 'in process'}, kinds
    assert sum(checked(code)[1] for _, _, code in BLOCKS) >= 3


@pytest.mark.parametrize('page,index,code', BLOCKS, ids=[f'{p}#{i}' for p, i, _ in BLOCKS])
def test_a_python_block_runs_as_its_page_says(page, index, code, server, tmp_path):
    script, _ = checked(code)
    path = tmp_path / 'block.py'
    path.write_text(script)
    what = kind(code)
    if what == 'in process':
        _run_in_process(path, tmp_path)
        return
    domain = _other_domain() if what == 'own node' else None
    env = _env(domain)
    env[MARK] = f'{os.getpid()}-{page}-{index}'   # inherited by every process it starts
    done = subprocess.run([sys.executable, str(path)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f'{page} block {index}:\n{done.stdout}\n{done.stderr}'
    # When the block ends its node has ended, workers and all.
    assert not _marked(env[MARK]), _marked(env[MARK])


MARK = 'PROJECTION_DOCS_BLOCK'


def _marked(mark: str) -> list[str]:
    """The command lines of the processes whose environment holds the mark."""
    found = []
    for proc in Path('/proc').iterdir():
        try:
            if f'{MARK}={mark}'.encode() in (proc / 'environ').read_bytes().split(b'\0'):
                found.append((proc / 'cmdline').read_bytes().replace(b'\0', b' ').decode())
        except (OSError, ValueError):   # not a process, or gone
            continue
    return found


def _run_in_process(path: Path, tmp_path: Path) -> None:
    import rclpy
    from rclpy.context import Context
    from projection_interfaces.srv import PrologQuery

    domain = _other_domain()
    proc = subprocess.Popen([sys.executable, str(path)], cwd=tmp_path, env=_env(domain),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    try:
        probe = rclpy.create_node('docs_python_probe', context=context)
        query = probe.create_client(PrologQuery, '/projection_server/query')
        assert query.wait_for_service(timeout_sec=120.0), 'the node of the block never served'
        from rclpy.executors import SingleThreadedExecutor
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(probe)
        future = query.call_async(PrologQuery.Request(query='X is 6 * 7', mode=PrologQuery.Request.ONCE))
        executor.spin_until_future_complete(future, timeout_sec=60.0)
        assert future.done() and future.result().ok, future.result()
        assert [json.loads(x) for x in future.result().solutions] == [{'X': 42}], \
            future.result()
        probe.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
        proc.send_signal(signal.SIGINT)
        try:
            out, _ = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
            pytest.fail(f'Ctrl-C did not end the block:\n{out}')
    assert proc.returncode in (0, -signal.SIGINT, 130), out
