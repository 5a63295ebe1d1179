"""Parameter descriptors carry ranges, as `ros2 param describe` and rqt show them; `ros2 param
dump` holds every parameter, and its file starts the node again with the same values."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
import subprocess

import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters
import yaml

from projection_server.client.discovery import handshake


def test_numeric_parameters_describe_their_ranges(call):
    names = ['max_engines', 'default_timeout', 'max_solutions', 'idle_timeout',
             'projection_workers', 'max_bags']
    r = call(DescribeParameters, 'describe_parameters', DescribeParameters.Request(names=names))
    ranges = {d.name: (d.integer_range or d.floating_point_range) for d in r.descriptors}
    assert all(len(ranges[n]) == 1 for n in names), ranges
    assert ranges['max_solutions'][0].from_value == 1
    assert ranges['default_timeout'][0].from_value > 0


def test_a_value_outside_its_range_is_refused(call):
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=-1.0)
    r = call(SetParameters, 'set_parameters', SetParameters.Request(
        parameters=[Parameter(name='idle_timeout', value=value)]))
    assert not r.results[0].successful


# --- ros2 param dump, and its file starting the node again ----------------------------------

SHARED_ROS2CLI = Path(__file__).resolve().parents[2] / 'shared' / 'ros2cli' / 'install.sh'


def _dump_over_services(node, name: str) -> dict:
    """What ``ros2 param dump`` does (ros2param's dump verb): list the names, get every value
    in one request, and nest them under the node's name."""
    from rclpy.parameter import parameter_value_to_python

    names = _request(node, ListParameters, f'{name}/list_parameters',
                     ListParameters.Request()).result.names
    names = sorted(names)
    values = _request(node, GetParameters, f'{name}/get_parameters',
                      GetParameters.Request(names=names)).values
    return {name: {'ros__parameters': {n: parameter_value_to_python(v)
                                        for n, v in zip(names, values)}}}


def _request(node, srv_type, service, request):
    import rclpy

    client = node.create_client(srv_type, service)
    try:
        assert client.wait_for_service(timeout_sec=20.0), service
        assert handshake(node, service.rsplit('/', 1)[0], 20.0), service
        future = client.call_async(request)
        rclpy.spin_until_future_complete(node, future, timeout_sec=20.0)
        assert future.done(), service
        return future.result()
    finally:
        node.destroy_client(client)


def _dump_with_ros2cli(node, name: str) -> dict:
    root = Path(__file__).resolve().parents[1]
    # One install per checkout: its ros2 wrapper runs inside that checkout's tools/with_env.sh
    # (and the install script is idempotent by its prefix alone).
    checkout = hashlib.sha1(str(root).encode()).hexdigest()[:12]
    cache = Path(os.environ.get('PROJECTION_SERVER_CACHE',
                                Path.home() / '.cache' / 'projection_server'))
    prefix = cache / f'ros2cli-{checkout}'
    subprocess.run(['bash', str(SHARED_ROS2CLI), str(prefix)], cwd=root, check=True,
                   capture_output=True, timeout=600)
    done = subprocess.run([str(prefix / 'ros2'), 'param', 'dump', '--no-daemon', '--timeout',
                           '20', name], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.startswith(name), (done.stdout, done.stderr)
    return yaml.safe_load(done.stdout)


@pytest.mark.parametrize('dump', [
    _dump_over_services,
    pytest.param(_dump_with_ros2cli, marks=pytest.mark.skipif(
        not SHARED_ROS2CLI.is_file(), reason='the real ros2 command line is not at hand')),
], ids=['services', 'ros2cli'])
def test_a_dump_holds_every_parameter_and_its_file_starts_the_node_again(
        rclpy_context, node, tmp_path, dump):
    from projection_server.client.launcher import node_command, NodeProcess

    name = f'/dumped_{dump.__name__.strip("_")}_{os.getpid()}'
    params = {'bag_dir': str(tmp_path / 'bags'), 'max_solutions': 7, 'default_timeout': 9.5,
              'sandbox': False}
    with NodeProcess(node_command(name, params), tmp_path / 'first.log') as proc:
        proc.wait_for_service(f'{name}/query')
        first = dump(node, name)
    values = first[name]['ros__parameters']
    # every declared parameter, the unset-looking string arrays as empty lists
    assert values['kb_files'] == [] and values['asset_paths'] == [], values
    assert values['max_solutions'] == 7 and values['sandbox'] is False, values
    assert {'max_engines', 'projection_workers', 'idle_timeout', 'bag_dir'} <= set(values)
    file = tmp_path / 'params.yaml'
    file.write_text(yaml.safe_dump(first))
    command = node_command(name, {}) + ['--params-file', str(file)]
    with NodeProcess(command, tmp_path / 'second.log') as proc:
        proc.wait_for_service(f'{name}/query')
        assert dump(node, name) == first
