"""Bags: the project's messages round-trip through an MCAP bag."""

from __future__ import annotations

import pytest

from projection_server.bags import BagWriter, message_definitions, read_bag
from projection_server.simulation import ProjectionError


def test_message_definitions_are_found():
    names = set(message_definitions())
    assert {'projection_interfaces/msg/Contact', 'projection_interfaces/msg/ContactArray',
            'projection_interfaces/msg/GripperState', 'projection_interfaces/msg/ObjectState',
            'projection_interfaces/msg/ProjectionInfo'} <= names


def test_project_messages_round_trip(tmp_path):
    path = tmp_path / 'bag'
    with BagWriter(path) as bag:
        stamp = bag.new('builtin_interfaces/msg/Time', sec=1, nanosec=500)
        header = bag.new('std_msgs/msg/Header', stamp=stamp, frame_id='world')
        state = bag.new('projection_interfaces/msg/ObjectState', name='egg1', load=4.5,
                        load_limit=10.0, broken=True)
        bag.write('/projection/objects', bag.new(
            'projection_interfaces/msg/ObjectStateArray', header=header, objects=[state]),
            1_000_000_500)
    ((topic, t_ns, msg),) = list(read_bag(path))
    assert (topic, t_ns) == ('/projection/objects', 1_000_000_500)
    assert (msg.objects[0].name, msg.objects[0].load, msg.objects[0].broken) == (
        'egg1', 4.5, True)
    assert (path / 'bag.mcap').is_file()


def test_an_existing_bag_is_never_overwritten(tmp_path):
    (tmp_path / 'bag').mkdir()
    with pytest.raises(ProjectionError) as info:
        with BagWriter(tmp_path / 'bag'):
            pass
    assert info.value.kind == 'bag_error'


def test_reading_a_missing_bag_is_a_bag_error(tmp_path):
    with pytest.raises(ProjectionError) as info:
        list(read_bag(tmp_path / 'nothing'))
    assert info.value.kind == 'bag_error'
