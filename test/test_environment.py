"""tools/with_env.sh, the environment every command runs in: a ROS workspace the user has
sourced keeps its prefixes, after this package's."""

from __future__ import annotations

import os
from pathlib import Path
import subprocess

ROOT = Path(__file__).resolve().parents[1]


def test_a_sourced_workspaces_ament_prefixes_are_kept():
    env = {**os.environ, 'AMENT_PREFIX_PATH': '/opt/my_ws/install:/opt/ros/jazzy'}
    out = subprocess.run([str(ROOT / 'tools' / 'with_env.sh'), 'printenv',
                          'AMENT_PREFIX_PATH'], env=env, capture_output=True, text=True,
                         check=True).stdout.strip().split(':')
    assert '/opt/my_ws/install' in out and '/opt/ros/jazzy' in out
    assert out.index('/opt/my_ws/install') < out.index('/opt/ros/jazzy')
    ours = [p for p in out if p.startswith(str(ROOT))]
    assert ours and out.index(ours[0]) < out.index('/opt/my_ws/install')
