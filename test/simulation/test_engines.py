"""The engine protocol on MuJoCo: what the monitor, the object models and the programs read
means on it what it means on PyBullet (poses, transforms, contact points and their signs),
and a program or unit an engine cannot run is refused before any world is built."""

from __future__ import annotations

import copy
import math

import numpy as np
import pybullet
import pybullet_data
import pytest

from projection_server.simulation import load_settings, ProjectionError
from projection_server.simulation import engines
from projection_server.simulation.engines.mujoco.physics import MujocoPhysics
from projection_server.simulation.physics import bound_client
from projection_server.simulation.scenario import parse_scenario
from projection_server.simulation.world import settle

from .conftest import PANDA


@pytest.fixture(scope='module')
def bullet():
    client = bound_client(pybullet.DIRECT)
    yield client
    client.disconnect()


def mujoco_world(scenario, **physics):
    settings = load_settings().for_projection('wait', {'engine': 'mujoco', **physics})
    return engines.get('mujoco').open().build_world(parse_scenario(scenario), settings)


@pytest.mark.parametrize('rpy', [(0.3, -0.7, 2.1), (math.pi / 2, 0.0, 0.0), (0.0, 1.2, -3.0)])
def test_the_transform_algebra_is_pybullets(bullet, rpy):
    q = MujocoPhysics.quaternion_from_euler(rpy)
    assert np.allclose(q, bullet.getQuaternionFromEuler(rpy), atol=1e-12)
    assert np.allclose(MujocoPhysics.rotation_matrix(q),
                       np.reshape(bullet.getMatrixFromQuaternion(q), (3, 3)), atol=1e-12)
    p1, p2 = (0.1, -0.2, 0.3), (-0.5, 0.4, 0.05)
    q2 = MujocoPhysics.quaternion_from_euler((0.2, 0.1, -0.4))
    ours = MujocoPhysics.multiply_transforms(p1, q, p2, q2)
    theirs = bullet.multiplyTransforms(p1, q, p2, q2)   # in single precision
    assert np.allclose(ours[0], theirs[0], atol=1e-6) and _same_turn(ours[1], theirs[1])
    ours, theirs = MujocoPhysics.invert_transform(p1, q), bullet.invertTransform(p1, q)
    assert np.allclose(ours[0], theirs[0], atol=1e-6) and _same_turn(ours[1], theirs[1])


def _same_turn(a, b):
    """q and -q are the same rotation."""
    return np.allclose(a, b, atol=1e-6) or np.allclose(a, -np.asarray(b), atol=1e-6)


def test_an_egg_at_rest_is_carried_by_the_table_with_the_protocols_signs(make_scenario):
    physics = mujoco_world(make_scenario())
    settle(physics)
    egg, table = physics.bodies['egg1'].body_id, physics.bodies['table1'].body_id
    assert table < egg   # built in the scenario's order: the table is body a of the pair
    (point,) = [p for p in physics.contact_points(egg) if p[2] == table]
    assert point[1] == egg and point[3] == -1 and point[4] == -1
    assert point[9] == pytest.approx(0.06 * 9.81, rel=0.02)   # its weight
    # The normal points from b to a from either body (from the later one, turned round, as
    # PyBullet answers): up from the egg, down from the table.
    assert point[7][2] == pytest.approx(1.0, abs=1e-6)
    (other,) = [p for p in physics.contact_points(table) if p[2] == egg]
    assert other[7][2] == pytest.approx(-1.0, abs=1e-6) and other[9] == point[9]
    (sample,) = [c for c in physics.contacts() if c.body_b == 'table1' or c.body_a == 'table1']
    assert sample.normal_force == pytest.approx(point[9])
    position, orientation = physics.pose('egg1')
    assert position[2] == pytest.approx(0.72 + 0.022, abs=5e-4)
    assert np.allclose(orientation, (0, 0, 0, 1), atol=1e-3)


def test_a_gripper_closes_at_its_speed_and_pushes_with_the_force_asked_for(make_scenario):
    physics = mujoco_world(make_scenario())
    gripper = physics.grippers['pr2_robot']
    gripper.place((0.0, 0.5, 1.0), (0.0, 0.0, 0.0, 1.0), approach=0.0, lift=0.0,
                  opening=0.07)
    gripper.close(4.0, 0.03)
    rate = physics.settings.physics.rate_hz
    for _ in range(round(0.1 * rate)):   # 0.1 s in the air: closes at 0.03 m/s a finger
        physics.step()
    assert gripper.opening() == pytest.approx(0.07 - 2 * 0.03 * 0.1, abs=1e-3)
    for _ in range(2 * rate):   # closed on nothing: against its joint limits
        physics.step()
    assert gripper.command == 'close' and gripper.commanded_force == 4.0


@pytest.mark.parametrize('engine', ['pybullet', 'mujoco'])
@pytest.mark.parametrize('robot', ['panda', 'pr2'])
def test_fingers_closed_on_nothing_stop_at_their_joint_limits(make_scenario, engine, robot):
    # PyBullet's limits hold a finger pushed into them with 20 N; MuJoCo's are soft, and
    # at their default softness let it sink (1 - d) timeconst^2 F/m past: 4 mm of the
    # Panda's 0.1 kg fingers, 23 mm of the PR2's 20 g ones (at the drives' d, 8 um and
    # 40 um; PyBullet's PR2 0.14 mm). Both hands close to 0, their joints' lower limits.
    scenario = make_scenario()
    if robot == 'panda':
        scenario['entities'][1] = copy.deepcopy(PANDA)
    name = scenario['entities'][1]['name']
    del scenario['entities'][2]   # nothing between the pads
    settings = load_settings().for_projection('plan', {'engine': engine})
    session = engines.get(engine).open()
    try:
        physics = session.build_world(parse_scenario(scenario), settings, tool_control=True)
        gripper = physics.grippers[name]
        gripper.close(20.0, 0.1)
        for _ in range(int(1.0 * settings.physics.rate_hz)):   # closed by 0.5 s, then held
            physics.step()
        opening, force = gripper.state()
    finally:
        session.close()
    assert opening == pytest.approx(0.0, abs=2 * 0.25e-3), opening   # 0.25 mm a finger
    assert force == pytest.approx(20.0, rel=0.1)   # PyBullet's PR2 motor: 18.4 N of it


@pytest.mark.parametrize('engine', ['pybullet', 'mujoco'])
@pytest.mark.parametrize('robot', ['panda', 'pr2'])
def test_a_frame_recorder_gives_the_poses_of_frame_poses_bit_for_bit(make_scenario, engine,
                                                                      robot):
    # The monitor's frames (a robot's links as a chain relative to their parents, the egg
    # in the world) read sample by sample and handed over as arrays: the numbers that
    # frame_poses gives at each sample, to the last bit, while the fingers close.
    from projection_server.simulation.monitor import Monitor

    scenario = make_scenario()
    if robot == 'panda':
        scenario['entities'][1] = copy.deepcopy(PANDA)
    name = scenario['entities'][1]['name']
    settings = load_settings().for_projection('plan', {'engine': engine})
    session = engines.get(engine).open()
    try:
        physics = session.build_world(parse_scenario(scenario), settings, tool_control=True)
        monitor = Monitor(physics, bag=None)
        monitor._plan()
        frames = monitor._frames
        assert any(chain for _, _, chain in frames)   # some links relative to parents
        recorder = physics.frame_recorder(frames)
        physics.grippers[name].close(5.0, 0.1)
        expected = []
        for step in range(40):
            physics.step()
            if step % 4 == 0:
                recorder.add()
                expected.append(physics.frame_poses(frames))
            if step == 20:   # what was added so far, then a new block
                positions, quaternions = recorder.take()
                assert positions.shape == (len(expected), len(expected[0]), 3)
                _same_bits(positions, quaternions, expected)
                expected = []
        positions, quaternions = recorder.take()
    finally:
        session.close()
    _same_bits(positions, quaternions, expected)
    empty = recorder.take()
    assert empty[0].shape[0] == 0 and empty[1].shape[0] == 0


def _same_bits(positions, quaternions, expected):
    assert positions.tobytes() == np.array([[p for p, _ in row] for row in expected]).tobytes()
    assert quaternions.tobytes() == np.array([[q for _, q in row]
                                              for row in expected]).tobytes()


def test_a_program_or_a_shape_an_engine_cannot_run_is_refused(make_scenario):
    scenario = parse_scenario(make_scenario())
    engines.check('mujoco', 'grasp_object', scenario)
    engines.check('pybullet', 'pour', scenario)
    with pytest.raises(ProjectionError) as info:
        engines.check('mujoco', 'pour', scenario)
    assert 'pour' in str(info.value) and 'mujoco' in str(info.value)
    with pytest.raises(ProjectionError) as info:
        engines.get('ode')
    assert 'pybullet' in str(info.value) and 'mujoco' in str(info.value)


def test_a_mujoco_projection_made_twice_logs_the_same_bag(make_scenario, tmp_path):
    # The second world is a copy of the first one's compiled model, with a fresh state.
    from rosbags.highlevel import AnyReader

    from projection_server.bags import typestore
    from projection_server.simulation import Job
    from projection_server.simulation.runner import Simulator

    def messages(path):
        with AnyReader([path], default_typestore=typestore()) as reader:
            return [(c.topic, t, raw) for c, t, raw in reader.messages()
                    if c.topic != '/projection/info']

    job = Job.checked(make_scenario(), 'grasp_object', {'force': 11.0, 'position': 0.02},
                      {'engine': 'mujoco'})
    simulator = Simulator()
    try:
        first = simulator.run(job, load_settings(), tmp_path / 'first')
        second = simulator.run(job, load_settings(), tmp_path / 'second')
    finally:
        simulator.close()
    assert first.physics.models[0].broken and second.physics.models[0].broken
    assert messages(tmp_path / 'first') == messages(tmp_path / 'second')


@pytest.mark.parametrize('shape, size, rest', [
    ('box', {'size_x': 0.04, 'size_y': 0.06, 'size_z': 0.08}, 0.04),
    ('cylinder', {'radius': 0.03, 'height': 0.1}, 0.05),
    ('sphere', {'radius': 0.025}, 0.025),
])
def test_each_primitive_comes_to_rest_on_the_table_at_its_own_height(make_scenario, shape,
                                                                      size, rest):
    scenario = make_scenario()
    scenario['entities'] = [scenario['entities'][0], {
        'name': 'thing', 'class': 'rigid_object',
        'pose': {'xyz': [0.1, 0.0, 0.72 + rest + 0.02], 'rpy': [0.0, 0.0, 0.0]},
        'properties': {'shape': shape, 'mass': 0.3, **size}}]
    physics = mujoco_world(scenario)
    for _ in range(240):
        physics.step()
    position, _ = physics.pose('thing')
    assert position[2] == pytest.approx(0.72 + rest, abs=1e-3)
    assert math.hypot(*physics.base_velocity(physics.bodies['thing'].body_id)[0]) < 1e-3
    (total,) = [c.normal_force for c in physics.contacts()]
    assert total == pytest.approx(0.3 * 9.81, rel=0.02)


def test_a_backend_whose_default_engine_is_mujoco_runs_a_job_that_names_none_on_it(
        make_scenario, tmp_path):
    # What the node's physics_engine parameter sets (projection.configure(engine=...)).
    import dataclasses
    import json

    from projection_server.simulation import Job
    from projection_server.workers.local import WorkerPool

    settings = load_settings()
    settings = dataclasses.replace(settings, physics=dataclasses.replace(settings.physics,
                                                                         engine='mujoco'))
    job = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0})
    with WorkerPool(tmp_path / 'bags', workers=1, settings=settings) as pool:
        result = pool.submit(job, timeout=60.0).result(60.0)
        with pytest.raises(ProjectionError) as info:
            pool.submit(Job.checked(make_scenario(), 'pour', {}), timeout=60.0)
    from pathlib import Path

    from rosbags.highlevel import AnyReader

    from projection_server.bags import typestore
    with AnyReader([Path(result.bag)], default_typestore=typestore()) as reader:
        (message,) = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(
            [c for c in reader.connections if c.topic == '/projection/info'])]
    assert json.loads(message.settings_json)['physics']['engine'] == 'mujoco'
    assert 'pour' in str(info.value) and 'mujoco' in str(info.value)


def test_a_urdfs_mesh_outside_the_asset_directories_is_refused_on_mujoco(tmp_path):
    from projection_server.simulation.engines.mujoco.urdf import load_urdf

    (tmp_path / 'part.obj').write_text('v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n'
                                       'f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n')
    urdf = tmp_path / 'thing.urdf'
    urdf.write_text('<robot name="thing"><link name="base"><collision><geometry>'
                    '<mesh filename="part.obj"/></geometry></collision></link></robot>')
    with pytest.raises(ProjectionError, match='outside|inside the asset directories'):
        load_urdf(str(urdf), 'thing1')


def test_a_mesh_file_of_several_objects_collides_as_one_hull_each_on_mujoco():

    from projection_server.simulation.engines.mujoco.urdf import load_urdf, obj_parts

    mug = f'{pybullet_data.getDataPath()}/objects/mug.urdf'
    parts = obj_parts(f'{pybullet_data.getDataPath()}/objects/mug_col.obj')
    assert len(parts) == 6 and all(len(v) >= 4 and f.max() < len(v) for v, f in parts)
    model = load_urdf(mug, 'mug1').compile()
    assert model.ngeom == 6 and model.nmesh == 6
