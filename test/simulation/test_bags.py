"""Bags: the project's messages round-trip through an MCAP bag; the per-sample messages
serialized from templates are rosbags' bytes."""

from __future__ import annotations

import numpy as np
import pytest

from projection_server.bags import BagWriter, message_definitions, read_bag, typestore
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


def test_the_writer_built_on_rosbags_internals_is_pinned_to_the_installed_rosbags():
    """bags/mcap.py subclasses rosbags' private writer internals of one release. Another
    rosbags falls back to rosbags' own writer; this test makes the change loud, so that
    mcap.py is checked against the new release (the byte tests below) and its pin moved."""
    from importlib.metadata import version

    from projection_server.bags.mcap import ROSBAGS_VERSION, writer_class

    assert version('rosbags') == ROSBAGS_VERSION, (
        f'rosbags {version("rosbags")} is installed, bags/mcap.py was written against '
        f'{ROSBAGS_VERSION}: check its subclasses against the new release')
    assert writer_class().__name__ == '_Writer'


def test_reading_a_missing_bag_is_a_bag_error(tmp_path):
    with pytest.raises(ProjectionError) as info:
        list(read_bag(tmp_path / 'nothing'))
    assert info.value.kind == 'bag_error'


# --- serialization from templates --------------------------------------------------------

def _randomized(message, variable, rng, prefix=''):
    """``message`` with each number at a path matching ``variable`` replaced by a random one
    of its type (in place)."""
    from fnmatch import fnmatchcase

    from rosbags.interfaces import Nodetype

    for name, (kind, detail) in typestore().get_msgdef(message.__msgtype__).fields:
        value, path = getattr(message, name), prefix + name
        if kind == Nodetype.NAME:
            _randomized(value, variable, rng, path + '.')
        elif kind == Nodetype.SEQUENCE and detail[0][0] == Nodetype.NAME:
            for i, item in enumerate(value):
                _randomized(item, variable, rng, f'{path}.{i}.')
        elif kind != Nodetype.BASE or detail[0] == 'string' or not any(
                fnmatchcase(path, p) for p in variable):
            continue   # strings and what no pattern matches are the prototype's
        elif detail[0] == 'float64':
            setattr(message, name, float(rng.normal()))
        elif detail[0] == 'int32':
            setattr(message, name, int(rng.integers(-2**31, 2**31)))
        elif detail[0] == 'uint32':
            setattr(message, name, int(rng.integers(0, 2**32)))
        elif detail[0] == 'bool':
            setattr(message, name, bool(rng.integers(2)))
        else:
            raise AssertionError(f'no random {detail[0]}')
    return message


def _numbers(message, template_variable, prefix=''):
    """The numbers of ``message`` at paths matching ``template_variable``, in order."""
    from fnmatch import fnmatchcase

    from rosbags.interfaces import Nodetype

    out = []
    for name, (kind, detail) in typestore().get_msgdef(message.__msgtype__).fields:
        value, path = getattr(message, name), prefix + name
        if kind == Nodetype.NAME:
            out += _numbers(value, template_variable, path + '.')
        elif kind == Nodetype.SEQUENCE and detail[0][0] == Nodetype.NAME:
            for i, item in enumerate(value):
                out += _numbers(item, template_variable, f'{path}.{i}.')
        elif kind == Nodetype.BASE and detail[0] != 'string' and any(
                fnmatchcase(path, p) for p in template_variable):
            out.append(value)
    return out


def _layouts():
    """Every layout the monitor writes per sample: (name, template, prototype)."""
    from projection_server.simulation import monitor

    frames = (('world', 'egg1'), ('world', 'pr2_robot'),
              ('pr2_robot', 'pr2_robot/lift_link'), ('pr2_robot/lift_link', 'pr2_robot/f1'))
    pairs = (('egg1', '', 'pr2_robot', 'r_finger'), ('egg1', '', 'table1', ''),
             ('pr2_robot', 'l_finger', 'spatula', 'blade'))
    yield 'tf', monitor._tf_template(frames)
    yield 'clock', monitor._clock_template()
    yield 'contacts (none)', monitor._contacts_template(())
    yield 'contacts', monitor._contacts_template(pairs)
    yield 'gripper', monitor._gripper_template('pr2_gripper', 'close', ('l_finger', 'r_f'))
    yield 'objects', monitor._objects_template(('egg1', 'egg22'))
    yield 'task', monitor._task_template(('pr2_robot', 3, 'move_to', 'egg1'))
    yield 'task (no plan, no target)', monitor._task_template(('pr2_robot', -1, 'wait', ''))
    yield 'particles (300)', monitor._particles_template(
        (('batter', 0.006, (0.95, 0.9, 0.6, 1.0), 300),))
    yield 'particles (2 fluids)', monitor._particles_template(
        (('batter', 0.006, (0.95, 0.9, 0.6, 1.0), 7), ('oil', 0.004, (1.0, 1.0, 0.0, 0.5), 0)))


@pytest.mark.parametrize('name', [name for name, _ in _layouts()])
def test_a_template_gives_the_bytes_of_rosbags_serializer(name):
    """Each per-sample message of the monitor, a fixed and a variable-size one, serialized
    from its template with random numbers is byte for byte rosbags' serialization of the
    message with those numbers, one message at a time and five at once (``pack_rows``)."""
    template = dict(_layouts())[name]
    store = typestore()
    rng = np.random.default_rng(len(name))
    rows = []
    for _ in range(5):
        message = _randomized(template.prototype(), template.variable, rng)
        expected = bytes(store.serialize_cdr(message, template.msgtype))
        values = _numbers(message, template.variable)
        assert len(values) == template.count
        assert template.pack(values) == expected
        decoded = store.deserialize_cdr(template.pack(values), template.msgtype)
        assert _numbers(decoded, template.variable) == values
        rows.append(values)
    # Many messages at once, from an array of their numbers: the same bytes, one after
    # the other.
    packed = template.pack_rows(np.array(rows, dtype=float).reshape(len(rows), -1))
    assert packed == b''.join(template.pack(values) for values in rows)


@pytest.mark.parametrize('name', ['bag', 'a bag: #2'])
def test_a_bags_files_are_those_rosbags_writes(tmp_path, name):
    """The writer's cached QoS and metadata.yaml layout give rosbags' own files (a name
    that YAML would quote is left to rosbags)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from projection_server.bags import offered_qos
    from projection_server.bags.cdr import definition

    store = typestore()
    messages = []
    for i, (topic, msgtype) in enumerate([('/projection/info', 'ProjectionInfo'),
                                          ('/projection/objects', 'ObjectStateArray')] * 3):
        message = store.types[f'projection_interfaces/msg/{msgtype}'](
            **_defaults(store, f'projection_interfaces/msg/{msgtype}'))
        messages.append((topic, message, 1_000 * i + 7))
    ours, theirs = tmp_path / 'ours' / name, tmp_path / 'theirs' / name
    ours.parent.mkdir()
    theirs.parent.mkdir()
    with BagWriter(ours) as bag:
        for topic, message, t in messages:
            bag.write(topic, message, t)
    with Writer(theirs, version=9, storage_plugin=StoragePlugin.MCAP) as bag:
        connections = {}
        for topic, message, t in messages:
            if topic not in connections:
                connections[topic] = bag.add_connection(
                    topic, message.__msgtype__, typestore=store,
                    offered_qos_profiles=[offered_qos(topic)])
            bag.write(connections[topic], t, store.serialize_cdr(message, message.__msgtype__))
    assert definition('projection_interfaces/msg/ObjectStateArray')[1].startswith('RIHS01_')
    metadata = (ours / 'metadata.yaml').read_text()
    assert metadata == (theirs / 'metadata.yaml').read_text()
    assert 'message_count: 6' in metadata and 'nanoseconds_since_epoch: 7' in metadata
    assert (ours / f'{name}.mcap').read_bytes() == (theirs / f'{name}.mcap').read_bytes()


@pytest.mark.parametrize('way', ['write_sample', 'write_samples'])
def test_a_samples_messages_written_at_once_are_the_bytes_of_rosbags_writer(tmp_path, way):
    """``write_sample`` (a monitoring step's messages in one call, topics new and old, and
    chunks that fill up in the middle of a sample) and ``write_samples`` (seven samples a
    call, a new topic in the middle of one) write rosbags' own files."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from projection_server.bags import offered_qos

    store = typestore()
    msgtype = 'projection_interfaces/msg/ProjectionInfo'
    samples = []
    for i in range(40):
        fields = _defaults(store, msgtype)
        fields['scenario_json'] = 'x' * (30_000 + 977 * i)   # 1 MiB chunks fill up
        message = store.types[msgtype](**fields)
        data = bytes(store.serialize_cdr(message, msgtype))
        topics = ['/a', '/b'] + (['/c'] if i >= 3 else []) + (['/b'] if i % 2 else [])
        samples.append((1_000 * i + 7, [(topic, msgtype, data) for topic in topics]))
    ours, theirs = tmp_path / 'ours' / 'bag', tmp_path / 'theirs' / 'bag'
    ours.parent.mkdir()
    theirs.parent.mkdir()
    with BagWriter(ours) as bag:
        if way == 'write_sample':
            for t, messages in samples:
                bag.write_sample(t, messages)
        else:
            for first in range(0, len(samples), 7):
                bag.write_samples(samples[first:first + 7])
    with Writer(theirs, version=9, storage_plugin=StoragePlugin.MCAP) as bag:
        connections = {}
        for t, messages in samples:
            for topic, msgtype, data in messages:
                if topic not in connections:
                    connections[topic] = bag.add_connection(
                        topic, msgtype, typestore=store,
                        offered_qos_profiles=[offered_qos(topic)])
                bag.write(connections[topic], t, data)
    assert (ours / 'metadata.yaml').read_text() == (theirs / 'metadata.yaml').read_text()
    mcap = (ours / 'bag.mcap').read_bytes()
    assert len(mcap) > 3 * 2**20
    assert mcap == (theirs / 'bag.mcap').read_bytes()


def _defaults(store, msgtype):
    from rosbags.interfaces import Nodetype

    fields = {}
    for name, (kind, detail) in store.get_msgdef(msgtype).fields:
        if kind == Nodetype.NAME:
            fields[name] = store.types[detail](**_defaults(store, detail))
        elif kind == Nodetype.SEQUENCE:
            fields[name] = []
        elif detail[0] == 'string':
            fields[name] = f'{name} text'
        elif detail[0] == 'bool':
            fields[name] = True
        else:
            fields[name] = 3 if 'int' in detail[0] else 2.5
    return fields


def test_a_projections_bag_holds_rosbags_bytes_and_its_timeline(tmp_path, make_scenario):
    """Every message of a real projection's bag is rosbags' serialization of itself, and
    the bag translates to the timeline the projection made from its samples in memory."""
    from projection_server.simulation import load_settings
    from projection_server.simulation.job import Job
    from projection_server.workers.run import run_projection
    from projection_server.workers.run import translate_bag

    from rosbags.highlevel import AnyReader

    job = Job.checked(make_scenario(), 'grasp_object', {'force': 11.0, 'position': 0.02})
    timeline = run_projection(job, load_settings(), tmp_path / 'grasp')
    store = typestore()
    counts: dict[str, int] = {}
    with AnyReader([tmp_path / 'grasp'], default_typestore=store) as reader:
        for connection, _, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            assert bytes(raw) == bytes(store.serialize_cdr(message, connection.msgtype))
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
    assert counts['/tf'] == counts['/clock'] == counts['/projection/contacts'] > 200
    assert counts['/projection/task'] == counts['/tf'] and counts['/robot_description'] == 1
    assert translate_bag(tmp_path / 'grasp') == timeline
    assert 'break' in [event[0] for event in timeline['events']]


def test_the_markers_of_a_layout_are_rosbags_bytes_of_the_message_itself():
    """Body markers are packed from a template of their layout (frames, shapes, offsets);
    at any time they are rosbags' serialization of the markers made for that time."""
    from projection_server.simulation.monitor import _marker, _markers_template
    from projection_server.simulation.physics import Shape

    store = typestore()
    layout = ((('table1', Shape('box', (1.0, 0.6, 0.04), (0.6, 0.4, 0.2, 1.0)), (0.0,) * 3),
               ('egg1', Shape('sphere', (0.058, 0.044, 0.044), (1.0, 1.0, 0.9, 1.0)),
                (0.0,) * 3),
               ('pancake1/s3', Shape('box', (0.02, 0.02, 0.01), (0.9, 0.8, 0.5, 1.0),
                                     (0.0, 0.0, 0.38, 0.92)), (0.01, -0.02, 0.003))))
    template = _markers_template(layout)
    for t in (0, 1_683_333_333, 12_000_000_001):
        message = store.types['visualization_msgs/msg/MarkerArray'](markers=[
            _marker(t, index, *marker) for index, marker in enumerate(layout)])
        sec, nanosec = divmod(t, 1_000_000_000)
        assert template.pack((sec, nanosec) * (2 * len(layout))) == bytes(
            store.serialize_cdr(message, 'visualization_msgs/msg/MarkerArray'))


def test_a_task_without_a_state_writes_no_task_states(tmp_path, make_scenario):
    from projection_server.simulation import load_settings
    from projection_server.simulation.job import Job
    from projection_server.workers.run import run_projection

    job = Job.checked(make_scenario(), 'wait', {'duration': 0.2})
    run_projection(job, load_settings(), tmp_path / 'wait')
    topics = {topic for topic, _, _ in read_bag(tmp_path / 'wait')}
    assert '/tf' in topics and '/robot_description' in topics
    assert '/projection/task' not in topics


def test_tf_blocks_are_equal_when_their_frames_times_and_poses_are():
    from projection_server.bags import TfBlock

    frames = (('world', 'egg1'),)
    poses = np.arange(6.0).reshape(2, 1, 3), np.arange(8.0).reshape(2, 1, 4)
    block = TfBlock(np.array([1, 2]), frames, *poses)
    assert block == TfBlock(np.array([1, 2]), frames, poses[0].copy(), poses[1].copy())
    moved = poses[0].copy()
    moved[1, 0, 2] += 1e-12
    assert block != TfBlock(np.array([1, 2]), frames, moved, poses[1])
    assert block != TfBlock(np.array([1, 3]), frames, *poses)
    assert block != TfBlock(np.array([1, 2]), (('world', 'egg2'),), *poses)
