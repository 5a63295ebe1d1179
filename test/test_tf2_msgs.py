"""The tf2_msgs the node subscribes with are ROS 2 Jazzy's: same package, fields and type
hashes, so that a robot's /tf (typed by Jazzy's own tf2_msgs) matches over DDS."""

from __future__ import annotations

import json
import os
from pathlib import Path

from rosbags.typesys import get_typestore, Stores
from tf2_msgs.msg import TF2Error, TFMessage


def _type_hash(package: str, name: str) -> str:
    for prefix in os.environ['AMENT_PREFIX_PATH'].split(os.pathsep):
        path = Path(prefix, 'share', package, 'msg', f'{name}.json')
        if path.is_file():
            hashes = json.loads(path.read_text())['type_hashes']
            return next(h['hash_string'] for h in hashes
                        if h['type_name'] == f'{package}/msg/{name}')
    raise AssertionError(f'no type description of {package}/msg/{name} installed')


def test_tfmessage_has_jazzys_type_hash():
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    assert _type_hash('tf2_msgs', 'TFMessage') == jazzy.hash_rihs01('tf2_msgs/msg/TFMessage')


def test_tf2error_has_jazzys_type_hash_and_constants():
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    assert _type_hash('tf2_msgs', 'TF2Error') == jazzy.hash_rihs01('tf2_msgs/msg/TF2Error')
    constants, _ = jazzy.fielddefs['tf2_msgs/msg/TF2Error']
    assert {name: value for name, _, value in constants} == {
        name: getattr(TF2Error, name) for name, _, _ in constants}


def test_tfmessage_holds_transforms_stamped():
    assert TFMessage.get_fields_and_field_types() == {
        'transforms': 'sequence<geometry_msgs/TransformStamped>'}
