"""``rigid_object``: a body of any shape, its mass and surface from its properties; a
moving mesh's convex decomposition made once; breakable like the egg."""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import pybullet
import pybullet_data
import pytest

from projection_server import assets
from projection_server.simulation import load_settings, ProjectionError
from projection_server.simulation.physics import bound_client
from projection_server.simulation.scenario import parse_scenario
from projection_server.simulation.world import build_world

DATA = Path(pybullet_data.getDataPath())
GLASS = str(assets.PACKAGE_ASSETS / 'glass.obj')
TABLE_TOP = 0.72
KITCHEN = {'name': 'kitchen_env', 'class': 'environment', 'properties': {}, 'parts': [
    {'name': 'floor1', 'class': 'floor', 'properties': {}},
    {'name': 'table1', 'class': 'table', 'pose': {'xyz': [0.0, 0.0, 0.7]},
     'properties': {'size_x': 1.2, 'size_y': 0.8, 'size_z': 0.04, 'height': TABLE_TOP}}]}


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    """A fresh cache of convex decompositions for each test."""
    monkeypatch.setenv('PROJECTION_SERVER_CACHE', str(tmp_path / 'cache'))
    return tmp_path / 'cache' / 'vhacd'


@pytest.fixture
def client():
    bullet = bound_client(pybullet.DIRECT)
    yield bullet
    bullet.disconnect()


def thing(name='thing1', xyz=(0.0, 0.0, 1.0), **properties):
    return {'name': name, 'class': 'rigid_object', 'pose': {'xyz': list(xyz)},
            'properties': properties}


def world(client, *entities):
    return build_world(client, parse_scenario({'name': 's', 'entities': [KITCHEN, *entities]}),
                       load_settings())


@pytest.mark.parametrize('properties, geometry', [
    ({'shape': 'box', 'size_x': 0.1, 'size_y': 0.2, 'size_z': 0.3}, pybullet.GEOM_BOX),
    ({'shape': 'cylinder', 'radius': 0.04, 'height': 0.1}, pybullet.GEOM_CYLINDER),
    ({'shape': 'sphere', 'radius': 0.03}, pybullet.GEOM_SPHERE),
    ({'shape': 'mesh', 'file': GLASS}, pybullet.GEOM_MESH),
])
def test_a_primitive_or_mesh_is_built_with_its_shape_and_mass(client, properties, geometry):
    physics = world(client, thing(mass=0.25, friction=0.42, **properties))
    body = physics.body('thing1').body_id
    info = client.getDynamicsInfo(body, -1)
    assert info[0] == pytest.approx(0.25) and info[1] == pytest.approx(0.42)
    assert {shape[2] for shape in client.getCollisionShapeData(body, -1)} == {geometry}
    assert not physics.body('thing1').static


def test_a_box_has_its_size(client):
    physics = world(client, thing(shape='box', size_x=0.1, size_y=0.2, size_z=0.3, mass=1.0))
    low, high = client.getAABB(physics.body('thing1').body_id)
    assert [h - lo for lo, h in zip(low, high)] == pytest.approx([0.1, 0.2, 0.3], abs=0.01)
    assert physics.body('thing1').shape.size == (0.1, 0.2, 0.3)


def test_a_urdf_is_loaded_with_its_mass_scaled_to_the_given_total(client):
    physics = world(client, thing(shape='urdf', file=str(DATA / 'objects' / 'mug.urdf'),
                                  mass=0.3, restitution=0.2))
    body = physics.body('thing1').body_id
    assert client.getDynamicsInfo(body, -1)[0] == pytest.approx(0.3)
    assert client.getDynamicsInfo(body, -1)[5] == pytest.approx(0.2)   # restitution
    assert physics.body('thing1').link_shapes[-1][0][0].kind == 'box'   # its bounding box


def test_a_urdf_without_a_mass_keeps_its_own_and_is_scaled(client):
    tray = str(DATA / 'tray' / 'traybox.urdf')
    physics = world(client, thing('small', (0.3, 0.0, 1.0), shape='urdf', file=tray, scale=0.5),
                    thing('large', (-0.3, 0.0, 1.0), shape='urdf', file=tray))
    small, large = (client.getAABB(physics.body(n).body_id) for n in ('small', 'large'))
    assert small[1][0] - small[0][0] == pytest.approx((large[1][0] - large[0][0]) / 2, rel=0.02)
    assert physics.body('small').static   # traybox.urdf's tray has no mass


def test_a_static_mesh_stays_concave_and_is_not_decomposed(client, cache):
    physics = world(client, thing(shape='mesh', file=GLASS, mass=0.0))
    assert physics.body('thing1').static
    assert not cache.exists()


def test_a_moving_mesh_is_decomposed_once_and_the_decomposition_reused(client, cache):
    world(client, thing(shape='mesh', file=GLASS, mass=0.2))
    (made,) = cache.glob('*.obj')
    stamp = made.stat().st_mtime_ns
    physics = world(client, thing(shape='mesh', file=GLASS, mass=0.2, scale=2.0))
    assert list(cache.glob('*')) == [made] and made.stat().st_mtime_ns == stamp
    parts = client.getCollisionShapeData(physics.body('thing1').body_id, -1)
    assert len(parts) > 1   # a hollow glass is more than one convex part


def test_processes_decomposing_at_once_each_get_the_whole_decomposition(cache):
    code = ('import sys; from projection_server.simulation.objects.rigid_object import '
            'convex_decomposition; print(convex_decomposition(sys.argv[1]))')
    processes = [subprocess.Popen([sys.executable, '-c', code, GLASS], text=True,
                                  stdout=subprocess.PIPE) for _ in range(2)]
    results = [p.communicate(timeout=120)[0].strip() for p in processes]
    assert [p.returncode for p in processes] == [0, 0]
    assert results[0] == results[1]
    assert [p.name for p in cache.iterdir()] == [Path(results[0]).name]
    assert assets.resolve(results[0], [str(cache)])[0] == 'ok'


def test_a_meshs_centre_of_mass_is_the_centroid_of_its_volume(client):
    # The glass stands on its base: its centre of mass is low, inside the base's half.
    physics = world(client, thing(shape='mesh', file=GLASS, mass=0.2, xyz=(0, 0, TABLE_TOP)))
    position = client.getBasePositionAndOrientation(physics.body('thing1').body_id)[0]
    assert TABLE_TOP + 0.02 < position[2] < TABLE_TOP + 0.05


def drop(client, height: float, breaking_force: float, steps: int = 240):
    physics = world(client, thing(shape='mesh', file=GLASS, mass=0.22, restitution=0.1,
                                  breaking_force=breaking_force,
                                  xyz=(0.0, 0.0, TABLE_TOP + height)))
    for _ in range(steps):
        physics.step()
    return physics


def test_a_glass_dropped_onto_the_table_breaks_only_above_its_breaking_force(client):
    assert not drop(client, 0.10, 40.0).models[0].broken
    assert drop(client, 0.10, 5.0).models[0].broken
    assert drop(client, 0.60, 40.0).models[0].broken


def test_a_resting_object_loads_its_contact_with_its_weight(client):
    physics = world(client, thing(shape='box', size_x=0.1, size_y=0.1, size_z=0.1, mass=0.5,
                                  breaking_force=100.0, xyz=(0.0, 0.0, TABLE_TOP + 0.05)))
    for _ in range(120):
        physics.step()
    assert physics.object_load('thing1') == pytest.approx(0.5 * 9.81, rel=0.05)


def test_a_broken_object_stays_and_no_robot_holds_it(client, make_scenario):
    scenario = make_scenario()
    scenario['entities'].append(thing(shape='box', size_x=0.05, size_y=0.05, size_z=0.05,
                                      mass=0.1, breaking_force=1.0))
    physics = build_world(client, parse_scenario(scenario), load_settings())
    box = physics.body('thing1').body_id
    robot = next(b for b in physics.bodies.values() if b.driven)
    where = client.getBasePositionAndOrientation(robot.body_id)[0]
    client.resetBasePositionAndOrientation(box, where, (0, 0, 0, 1))
    client.performCollisionDetection()
    assert client.getContactPoints(box, robot.body_id)
    model = physics.models[-1]
    model._replace(physics, 'thing1')
    client.performCollisionDetection()
    assert not client.getContactPoints(box, robot.body_id)
    assert physics.body('thing1').body_id == box


@pytest.mark.parametrize('properties, message', [
    ({'shape': 'cone', 'radius': 0.1, 'mass': 1.0}, "unknown shape 'cone'"),
    ({'shape': 'box', 'size_x': 0.1, 'size_y': 0.1, 'mass': 1.0}, 'a box needs size_z'),
    ({'shape': 'sphere', 'radius': 0.1, 'height': 0.2, 'mass': 1.0},
     'height is not a property of a sphere'),
    ({'shape': 'box', 'size_x': 0.1, 'size_y': 0.1, 'size_z': 0.1}, 'a box needs a mass'),
    ({'shape': 'mesh', 'file': '/x/mug.urdf', 'mass': 1.0}, 'the file of a mesh is a .obj'),
    ({'shape': 'urdf', 'file': '/x/glass.obj'}, 'the file of a urdf is a .urdf'),
    ({'shape': 'sphere', 'radius': -0.1, 'mass': 1.0}, 'radius = -0.1 is not positive'),
])
def test_a_shape_takes_its_own_properties_and_no_others(properties, message):
    with pytest.raises(ProjectionError) as info:
        parse_scenario({'name': 's', 'entities': [thing(**properties)]})
    assert info.value.kind == 'invalid_scenario' and message in str(info.value)
