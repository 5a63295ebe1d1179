"""A node started from a script does not outlive it: two real scripts, each holding a
NodeProcess whose node is projecting pours on two workers; one is ended by SIGTERM, the
other by SIGKILL, and each node, its fork server and its workers are gone within seconds."""

from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from projection_interfaces.srv import PrologQuery

from projection_server.client.discovery import handshake

SCRIPT = '''
import sys, time
from pathlib import Path
import rclpy
from projection_server.client.launcher import node_command, NodeProcess
rclpy.init()
name, bags, log = sys.argv[1:4]
params = {'bag_dir': bags, 'projection_workers': 2}
with NodeProcess(node_command(name, params), Path(log)) as server:
    server.wait_for_service(f'/{name}/query')
    print(server.proc.pid, flush=True)
    time.sleep(600)
print('ended', flush=True)
'''
POURS = ('make_projection(pouring, pour, [(A, angle, [1.84, 1.99, 2.14]), '
         '(T, time, [1.0, 2.0, 3.0]), (P, position, [-0.09, 0.0, 0.03])], _)')
GONE_WITHIN = 30.0   # s: a loaded machine's margin; an orphan lives on


def _alive(pid: int) -> bool:
    """The process exists and is not a zombie (a reaper may be slow to collect it)."""
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return False
    return stat.rsplit(')', 1)[1].split()[0] != 'Z'


def _descendants(root: int) -> set[int]:
    children: dict[int, list[int]] = {}
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / 'stat').read_text().rsplit(')', 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry.name))
    found, todo = set(), [root]
    while todo:
        for child in children.get(todo.pop(), []):
            found.add(child)
            todo.append(child)
    return found


def _start(tmp_path: Path, name: str) -> tuple[subprocess.Popen[str], int]:
    script = tmp_path / 'script.py'
    script.write_text(SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script), name, str(tmp_path / name),
                             str(tmp_path / f'{name}.log')], stdout=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.strip().isdigit(), (line, (tmp_path / f'{name}.log').read_text())
    return proc, int(line)


def _busy_workers(node_pid: int, timeout: float = 60.0) -> set[int]:
    """The node's processes once its workers project (their trees forked)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        tree = _descendants(node_pid)
        if len(tree) >= 5:   # resource tracker, fork server, 2 workers, a tree's process
            return tree
        time.sleep(0.2)
    raise AssertionError(f'the node {node_pid} did not start projecting: {tree}')


def test_a_scripts_node_and_its_workers_end_with_the_script(rclpy_context, node, tmp_path):
    suffix = os.getpid()
    scripts = {sig: _start(tmp_path, f'lifetime_{sig.name.lower()}_{suffix}')
               for sig in (signal.SIGTERM, signal.SIGKILL)}
    clients = []
    for sig, (_, _) in scripts.items():   # keep both nodes' workers busy with pours
        client = node.create_client(
            PrologQuery, f'/lifetime_{sig.name.lower()}_{suffix}/query')
        assert client.wait_for_service(timeout_sec=20.0)
        assert handshake(node, f'/lifetime_{sig.name.lower()}_{suffix}', 20.0)
        client.call_async(PrologQuery.Request(mode=PrologQuery.Request.ALL_SOLUTIONS,
                                              query=POURS, timeout=300.0))
        clients.append(client)
    processes = {sig: {script.pid, pid} | _busy_workers(pid)
                 for sig, (script, pid) in scripts.items()}
    for sig, (script, _) in scripts.items():
        script.send_signal(sig)
    deadline = time.monotonic() + GONE_WITHIN
    while time.monotonic() < deadline and any(
            map(_alive, set().union(*processes.values()))):
        time.sleep(0.1)
    left = {sig.name: sorted(p for p in pids if _alive(p)) for sig, pids in processes.items()}
    assert left == {'SIGTERM': [], 'SIGKILL': []}, left
    # SIGTERM was handled like Ctrl-C: the block stopped the node, the script exited 143.
    term, _ = scripts[signal.SIGTERM]
    assert term.wait(5.0) == 128 + signal.SIGTERM
    assert scripts[signal.SIGKILL][0].wait(5.0) == -signal.SIGKILL
    for client in clients:
        node.destroy_client(client)


def test_a_node_that_crashes_leaves_every_threads_stack_in_its_log(rclpy_context, node,
                                                                  tmp_path):
    """A crash in native code (here a SIGSEGV sent to a node that has answered a query)
    is not a silent exit: its log says what happened and where each thread was."""
    from projection_server.client.launcher import node_command, NodeProcess
    from test.nodes import caller

    name = f'crashing_{os.getpid()}'
    log = tmp_path / 'node.log'
    with NodeProcess(node_command(name, {'bag_dir': str(tmp_path / 'bags')}), log) as proc:
        proc.wait_for_service(f'/{name}/query')
        with caller(f'/{name}', node) as call:
            answer = call(PrologQuery, 'query', PrologQuery.Request(
                mode=PrologQuery.Request.ONCE, query='X = 1'))
            assert answer.ok, answer.message
        os.kill(proc.proc.pid, signal.SIGSEGV)
        assert proc.proc.wait(20.0) == -signal.SIGSEGV
    text = log.read_text()
    assert 'Fatal Python error: Segmentation fault' in text, text[-3000:]
    assert text.count('Thread 0x') >= 2, text[-3000:]   # the executor's threads too
