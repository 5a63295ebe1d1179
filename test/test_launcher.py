"""The node launcher: command lines, waiting for a service, stopping (with stand-in processes)."""

from __future__ import annotations

import signal
import sys
import time

import pytest

from projection_server.client.launcher import LaunchError, node_command, NodeProcess


def _python(code: str) -> list[str]:
    return [sys.executable, '-c', code]


def test_command_line_with_parameters():
    assert node_command('projection_server', {'max_engines': 4, 'bag_dir': '/tmp/b'}) == [
        'projection_server', '--ros-args', '-r', '__node:=projection_server',
        '-p', 'max_engines:=4', '-p', 'bag_dir:=/tmp/b']


def test_command_line_with_namespace_and_yaml_booleans():
    assert node_command('/robot/server', {'verbose': True}, executable='/bin/ps') == [
        '/bin/ps', '--ros-args', '-r', '__ns:=/robot', '-r', '__node:=server',
        '-p', 'verbose:=true']


def test_missing_executable(tmp_path):
    with pytest.raises(LaunchError, match='cannot start'):
        NodeProcess(['/nonexistent/projection_server'], tmp_path / 'node.log')


def test_exit_before_service_shows_the_log(rclpy_context, tmp_path):
    command = _python("print('lots of startup'); print('the reason'); raise SystemExit(3)")
    with NodeProcess(command, tmp_path / 'node.log') as proc, \
            pytest.raises(LaunchError, match='exited with code 3') as info:
        proc.wait_for_service('/launcher_test/query', timeout=30.0)
    assert str(info.value).endswith('the reason\n')


def test_timeout_waiting_for_service(rclpy_context, tmp_path):
    with NodeProcess(['sleep', '30'], tmp_path / 'node.log') as proc, \
            pytest.raises(LaunchError, match='not available after 1 s'):
        proc.wait_for_service('/launcher_test/query', timeout=1.0)
    assert proc.returncode == -signal.SIGINT


def test_stop_escalates_when_sigint_is_ignored(tmp_path):
    log = tmp_path / 'node.log'
    command = _python('import signal, sys, time\n'
                      'signal.signal(signal.SIGINT, signal.SIG_IGN)\n'
                      "print('ready', flush=True)\n"
                      'time.sleep(30)')
    proc = NodeProcess(command, log, stop_timeout=0.5)
    while 'ready' not in log.read_text() and proc.running:
        time.sleep(0.05)
    assert proc.stop() == -signal.SIGTERM
    assert proc.stop() == -signal.SIGTERM  # stopping again is harmless
