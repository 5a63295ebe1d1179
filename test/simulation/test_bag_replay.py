"""Projection bags replay as ROS 2 tools expect: offered QoS, /clock, the robot's tf chain."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosReliability

from projection_server.bags import read_bag, typestore
from projection_server.simulation import Job
from projection_server.workers.run import translate_bag

FINGERS = ('pr2_robot/l_finger', 'pr2_robot/r_finger')


@pytest.fixture
def grasp_bag(pool, make_scenario) -> Path:
    # The pool keeps the bag: every test of the module after the first reads the same one.
    job = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0, 'position': 0.0})
    return Path(pool.run(job, timeout=60.0))


def test_every_topic_records_the_qos_its_publisher_offers(grasp_bag):
    with AnyReader([grasp_bag], default_typestore=typestore()) as reader:
        offered = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    assert {'/tf', '/tf_static', '/clock', '/projection/info'} <= set(offered)
    for topic, profiles in offered.items():
        assert len(profiles) == 1, topic
        assert profiles[0].reliability == QosReliability.RELIABLE, topic
        latched = topic in ('/tf_static', '/projection/info', '/robot_description')
        assert profiles[0].durability == (QosDurability.TRANSIENT_LOCAL if latched
                                          else QosDurability.VOLATILE), topic


def test_the_robot_description_names_its_links_as_their_tf_frames(grasp_bag):
    import xml.etree.ElementTree as ET

    ((_, t, message),) = read_bag(grasp_bag, ['/robot_description'])
    urdf = ET.fromstring(message.data)
    links = {link.get('name') for link in urdf.iter('link')}
    _, _, first = next(read_bag(grasp_bag, ['/tf']))
    frames = {tr.child_frame_id for tr in first.transforms}
    assert t == 0 and 'pr2_robot' in links and set(FINGERS) <= links <= frames
    for joint in urdf.iter('joint'):
        assert {joint.find('parent').get('link'), joint.find('child').get('link')} <= links
    # Every link the simulation has a shape of is drawn.
    assert all(link.find('visual') is not None for link in urdf.iter('link')
               if link.find('collision') is not None)


def test_the_task_state_of_every_sample_names_the_grasps_phase_and_target(grasp_bag):
    states = [(t, m.robot, m.step, m.action, m.target)
              for _, t, m in read_bag(grasp_bag, ['/projection/task'])]
    assert [t for t, *_ in states] == [t for _, t, _ in read_bag(grasp_bag, ['/tf'])]
    assert {state[1:3] + state[4:] for state in states} == {('pr2_robot', -1, 'egg1')}
    phases = [state[3] for state in states]
    assert sorted(set(phases), key=phases.index) == ['settle', 'approach', 'close', 'squeeze',
                                                     'lift', 'hold']


def test_the_metadata_file_carries_the_profiles_as_rosbag2_writes_them(grasp_bag):
    import yaml

    meta = yaml.safe_load((grasp_bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    qos = {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles']
           for t in meta['topics_with_message_count']}
    # rosbag2 (version 9) writes a list of profiles; an empty one replays as volatile.
    assert qos['/tf_static'][0]['durability'] == 'transient_local'
    assert qos['/tf'][0]['reliability'] == 'reliable'


def test_clock_carries_the_simulated_time_of_every_sample(grasp_bag):
    clock = [(t, m.clock.sec * 10**9 + m.clock.nanosec)
             for _, t, m in read_bag(grasp_bag, ['/clock'])]
    tf_times = [t for _, t, _ in read_bag(grasp_bag, ['/tf'])]
    assert [t for t, _ in clock] == tf_times
    assert all(t == stamp for t, stamp in clock)
    assert clock[-1][1] > 1e9   # seconds of simulated grasp, not wall-clock time


def test_the_gripper_links_form_a_chain_under_the_robot(grasp_bag):
    _, _, first = next(read_bag(grasp_bag, ['/tf']))
    parent = {tr.child_frame_id: tr.header.frame_id for tr in first.transforms}
    assert parent['pr2_robot'] == 'world'
    for finger in FINGERS:
        chain, frame = [], finger
        while frame != 'world':
            chain.append(frame)
            frame = parent[frame]
        assert chain[-1] == 'pr2_robot' and len(chain) >= 3, chain
    assert all(parent[f] == 'pr2_robot/palm' for f in FINGERS)
    assert parent['egg1'] == 'world'


def test_the_chain_composes_to_the_world_poses_the_timeline_uses(grasp_bag, pool,
                                                                   make_scenario):
    # Composing the chain gives the fingers' world poses: the grasp's outcome is unchanged.
    timeline = translate_bag(grasp_bag)
    assert 'lift' in {e[0] for e in timeline['events']}
    assert 'slip' not in {e[0] for e in timeline['events']}
    _, _, msg = list(read_bag(grasp_bag, ['/tf']))[-1]
    world = {}
    for tr in msg.transforms:
        t, q = tr.transform.translation, tr.transform.rotation
        base = world.get(tr.header.frame_id, (np.zeros(3), np.eye(3)))
        world[tr.child_frame_id] = (base[0] + base[1] @ np.array([t.x, t.y, t.z]),
                                    base[1] @ _matrix(q))
    gap = np.linalg.norm(world[FINGERS[0]][0] - world[FINGERS[1]][0])
    assert 0.02 < gap < 0.1   # the fingers hold an egg 4.4 cm across


def _matrix(q) -> np.ndarray:
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
