"""The package installs where ROS 2 tools look: `ros2 run` finds executables in
lib/<package>, `ros2 pkg` the package in the ament index, launch files its share files."""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import xml.etree.ElementTree as ET

import pytest

EXECUTABLES = ('projection_server', 'prolog_query', 'projection_standin_robot')


@pytest.fixture(scope='module')
def prefix() -> Path:
    from ament_index_python.packages import get_package_prefix
    return Path(get_package_prefix('projection_server'))


@pytest.mark.parametrize('name', EXECUTABLES)
def test_ros2_run_finds_the_executable_in_lib_of_the_package(prefix, name):
    path = prefix / 'lib' / 'projection_server' / name
    assert path.is_file() and os.access(path, os.X_OK), path
    assert not (prefix / 'bin' / name).exists()


def test_the_installed_prolog_query_runs(prefix):
    done = subprocess.run([prefix / 'lib' / 'projection_server' / 'prolog_query', '--help'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and 'exit status' in done.stdout


def test_package_xml_names_the_real_dependencies(prefix):
    root = ET.parse(prefix / 'share' / 'projection_server' / 'package.xml').getroot()
    depends = {e.text for e in root if e.tag.endswith('depend')}
    assert {'rclpy', 'rcl_interfaces', 'action_msgs', 'projection_interfaces',
            'rosgraph_msgs', 'tf2_msgs', 'python3-numpy', 'python3-yaml',
            'python3-tqdm'} <= depends
