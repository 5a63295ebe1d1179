"""prolog_query as a user meets it: no hangs, clean cancels, distinct exit codes."""

from __future__ import annotations

import json
import signal
import subprocess
import time

import pytest

from projection_server.client.cli import (EXIT_DEADLINE, EXIT_INTERRUPTED, EXIT_TERMINATED,
                                          EXIT_UNAVAILABLE)


def _start(*args: str) -> subprocess.Popen:
    return subprocess.Popen(['prolog_query', *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _run(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run(['prolog_query', *args], capture_output=True, text=True,
                          timeout=timeout)


def _stats(client) -> dict:
    from std_srvs.srv import Trigger
    return json.loads(client._call(client._ping, Trigger.Request()).message)


def _one_line(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and 'Traceback' not in stderr, stderr
    return lines[0]


def test_an_absent_server_is_reported_within_the_wait_with_where_to_look(rclpy_context):
    started = time.monotonic()
    done = _run('--server', '/nobody_here', '--wait', '2', 'X = 1', timeout=60.0)
    took = time.monotonic() - started
    assert done.returncode == EXIT_UNAVAILABLE
    line = _one_line(done.stderr)
    assert 'ROS_DOMAIN_ID' in line and 'make run' in line and '/nobody_here' in line
    assert took < 2.0 + 10.0, took   # the wait, plus starting Python and rclpy


def test_the_solution_cap_is_said_not_applied_silently(server):
    done = _run('--server', server, 'between(1, inf, X)')
    assert done.returncode == 0
    assert len(done.stdout.splitlines()) == 2 + 50   # header, rule, the test node's cap
    assert 'cap of 50' in _one_line(done.stderr)


def test_incremental_mode_prints_as_it_goes_and_obeys_sigterm(server, client):
    proc = _start('--server', server, '--mode', 'incremental', 'between(1, inf, X)')
    try:
        first = [proc.stdout.readline() for _ in range(3)]
        assert first == ['X = 1\n', 'X = 2\n', 'X = 3\n']
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30.0)
    finally:
        proc.kill()
    assert proc.returncode == EXIT_TERMINATED
    assert 'terminated' in _one_line(err)
    assert _stats(client)['open_incremental'] == 0


def test_ctrl_c_cancels_a_projection_query_on_the_server(server, client):
    # 400 projections: still running when the signal comes, however fast the machine.
    query = ('make_projection(grasping, grasp_object, [(F, force, range(2.1003, 6.1, 0.02)),'
             ' (P, position, [-0.012, 0.012])], TL)')
    proc = _start('--server', server, '--progress', '--timeout', '120', query)
    try:
        time.sleep(1.0)
        for _ in range(600):   # until the progress bar shows a projection done
            if _stats(client)['engines'] and proc.poll() is None:
                break
            time.sleep(0.1)
        time.sleep(3.0)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60.0)
    finally:
        proc.kill()
    assert proc.returncode == EXIT_INTERRUPTED, err
    assert err.strip().splitlines()[-1] == ('prolog_query: interrupted; the query was '
                                            'cancelled on the server')
    assert 'Traceback' not in err
    deadline = time.monotonic() + 15.0
    while _stats(client)['engines'] and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _stats(client)['engines'] == 0


def test_progress_shows_a_bar_of_the_projections(server):
    query = 'make_projection(grasping, grasp_object, [(F, force, [1, 5, 11])], TL)'
    done = _run('--server', server, '--progress', '--timeout', '120', query)
    assert done.returncode == 0, done.stderr
    assert '3/3' in done.stderr and 'grasp_object' in done.stderr
    assert len(done.stdout.splitlines()) == 2 + 3


@pytest.mark.parametrize('progress', [False, True])
def test_a_deadline_ends_the_command_with_its_own_exit_code(server, progress):
    # 200 projections: far more than one second's worth, however fast the machine.
    query = 'make_projection(grasping, grasp_object, [(F, force, range(2.3007, 6.3, 0.02))], TL)'
    started = time.monotonic()
    done = _run('--server', server, '--timeout', '120', '--deadline', '1',
                *(['--progress'] if progress else []), query)
    assert done.returncode == EXIT_DEADLINE, done.stderr
    assert 'deadline' in done.stderr.strip().splitlines()[-1]
    assert time.monotonic() - started < 30.0


def test_a_server_that_dies_under_a_running_query_is_reported(rclpy_context, tmp_path):
    from projection_server.client import PrologClient
    from projection_server.client.launcher import node_command, NodeProcess

    name = 'doomed_server'
    params = {'bag_dir': str(tmp_path / 'bags'), 'default_timeout': 300.0}
    watcher = PrologClient(f'/{name}', service_timeout=20.0)
    with NodeProcess(node_command(name, params), tmp_path / 'node.log') as node:
        node.wait_for_service(f'/{name}/query')
        # --wait bounds both the discovery of the server and its silence during the query:
        # 8 s leaves discovery a loaded machine's margin.
        proc = _start('--server', f'/{name}', '--wait', '8', 'repeat, fail')
        try:
            deadline = time.monotonic() + 60.0
            while _stats(watcher)['engines'] == 0:   # the query runs
                assert time.monotonic() < deadline and proc.poll() is None
                time.sleep(0.2)
            node._signal_group(signal.SIGKILL)
            killed = time.monotonic()
            _, err = proc.communicate(timeout=60.0)
            took = time.monotonic() - killed
        finally:
            proc.kill()
            watcher.close(finish=False)
    assert proc.returncode == EXIT_UNAVAILABLE, err
    assert 'stopped answering' in _one_line(err)
    assert took < 8.0 + 2.0 + 5.0, took   # --wait, ping period, a loaded machine's margin
