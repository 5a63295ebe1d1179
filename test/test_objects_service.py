"""Objects of any shape and model files of one's own, through the real node.

The node runs with an asset directory and a Turtle file of the test's own
(``asset_paths``, ``kb_files``). Outcomes are projections of the ``wait`` program: the
world runs with no robot in it (a glass falls onto the table, a mug rests on it), on both
engines (``physics(_{engine: E})``).
"""

from __future__ import annotations

import json
import os
import signal
import time

from projection_interfaces.srv import PrologQuery
import pytest

from projection_server.client.discovery import handshake

Q = PrologQuery.Request
NAME = 'objects_server'
SIM_TIMEOUT = 120.0

ENGINES = ('pybullet', 'mujoco')


def block(height: float) -> str:
    """An OBJ of a 6 cm square block ``height`` tall, origin at the centre of its bottom face
    (outward-facing triangles)."""
    return '\n'.join(
        [f'v {x} {y} {z}' for z in (0.0, height) for x, y in
         ((-0.03, -0.03), (0.03, -0.03), (0.03, 0.03), (-0.03, 0.03))]
        + ['f 1 3 2', 'f 1 4 3', 'f 5 6 7', 'f 5 7 8', 'f 1 2 6', 'f 1 6 5',
           'f 2 3 7', 'f 2 7 6', 'f 3 4 8', 'f 3 8 7', 'f 4 1 5', 'f 4 5 8']) + '\n'


CUBE = block(0.06)   # a 6 cm cube

MY_KB = '''
@prefix kitchen: <http://projection-server.org/ontology/kitchen#> .
kitchen:Block a <http://www.w3.org/2002/07/owl#Class> ;
    <http://www.w3.org/2000/01/rdf-schema#subClassOf> kitchen:RigidObject .
kitchen:cube1 a kitchen:Block ;
    kitchen:shape "mesh" ; kitchen:file "cube.obj"^^kitchen:ModelFile ;
    kitchen:mass 0.1 ; kitchen:friction 0.5 ; kitchen:restitution 0.1 ;
    kitchen:rolling_friction 0.0 ; kitchen:spinning_friction 0.0 ;
    kitchen:x 0.3 ; kitchen:y -0.25 ; kitchen:z 0.72 .
kitchen:cube_on_table a kitchen:Scenario ;
    kitchen:hasMember kitchen:kitchen_env , kitchen:cube1 .
'''

# The glass of the knowledge base, lifted 10 cm above its place on the table.
GLASS_DROP = '''create_scenario(S), add_to_scenario(S, [kitchen_env, glass1]),
    scenario_set_property(S, glass1, pose, _{xyz: [-0.2, 0.28, 0.82]})'''


@pytest.fixture(scope='module')
def own_files(tmp_path_factory):
    """An asset directory ``models/`` with good and bad files, a file beside it that no
    query may reach, and a Turtle file."""
    root = tmp_path_factory.mktemp('own')
    models = root / 'models'
    models.mkdir()
    (models / 'cube.obj').write_text(CUBE)
    (models / 'holes.obj').write_text('v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n')
    (models / 'nolink.urdf').write_text('<robot name="nothing"/>')
    (root / 'secret.obj').write_text(CUBE)
    os.symlink(root / 'secret.obj', models / 'link.obj')
    (root / 'my_kitchen.ttl').write_text(MY_KB)
    return root


@pytest.fixture(scope='module')
def objects_server(rclpy_context, own_files, tmp_path_factory):
    from projection_server.client.launcher import node_command, NodeProcess
    log = tmp_path_factory.mktemp('objects_node') / 'node.log'
    params = {'default_timeout': 5.0, 'max_engines': 4,
              'bag_dir': str(tmp_path_factory.mktemp('objects_bags')),
              'asset_paths': [str(own_files / 'models')],
              'kb_files': [str(own_files / 'my_kitchen.ttl')]}
    with NodeProcess(node_command(NAME, params), log) as proc:
        proc.wait_for_service(f'/{NAME}/query', timeout=60.0)
        yield f'/{NAME}'
    assert proc.returncode in (0, -signal.SIGINT), log.read_text()


@pytest.fixture(scope='module')
def ask(objects_server, node):
    """``ask(text)`` -> (response, solutions): an ALL_SOLUTIONS query."""
    import rclpy
    client = node.create_client(PrologQuery, f'{objects_server}/query')
    assert client.wait_for_service(timeout_sec=20.0) and handshake(node, objects_server, 20.0)

    def send(text):
        future = client.call_async(Q(mode=Q.ALL_SOLUTIONS, query=text, timeout=SIM_TIMEOUT))
        rclpy.spin_until_future_complete(node, future, timeout_sec=SIM_TIMEOUT * 2)
        assert future.done(), 'no answer from the node'
        response = future.result()
        return response, [json.loads(s) for s in response.solutions]

    yield send
    node.destroy_client(client)


def serves_on(ask):
    r, sols = ask('X = 1')
    assert r.ok and sols == [{'X': 1}]


def on(engine):
    return f'[physics(_{{engine: {engine}}})]'


@pytest.mark.parametrize('engine', ENGINES)
def test_a_glass_that_falls_10_cm_breaks_only_with_a_much_lower_breaking_force(ask, engine):
    r, sols = ask(GLASS_DROP + f''',
        make_projection(S, wait, [(_, duration, [1.0])], {on(engine)}, TL1),
        ( occurs(break, _, TL1) -> Default = break ; Default = whole ),
        quantity(max_load(glass1), Load, TL1),
        copy_scenario(S, Weak), scenario_set_property(Weak, glass1, breaking_force, 5.0),
        make_projection(Weak, wait, [(_, duration, [1.0])], {on(engine)}, TL2),
        ( occurs(break(glass1), _, TL2) -> Lower = break ; Lower = whole ),
        ( occurs(drop(glass1), _, TL2) -> Dropped = yes ; Dropped = no )''')
    assert r.ok, r.message
    (s,) = sols
    assert (s['Default'], s['Lower'], s['Dropped']) == ('whole', 'break', 'yes')
    assert 5.0 < s['Load'] < 40.0   # the KB glass's breaking_force is 40 N


@pytest.mark.parametrize('engine', ENGINES)
def test_a_heavier_glass_breaks_where_the_default_does_not(ask, engine):
    r, sols = ask(GLASS_DROP + f''',
        member(M, [0.22, 0.5]), copy_scenario(S, C), scenario_set_property(C, glass1, mass, M),
        make_projection(C, wait, [(_, duration, [1.0])], {on(engine)}, TL),
        ( occurs(break(glass1), _, TL) -> O = break ; O = whole )''')
    assert r.ok, r.message
    assert [(s['M'], s['O']) for s in sols] == [(0.22, 'whole'), (0.5, 'break')]


@pytest.mark.parametrize('engine', ENGINES)
def test_the_mug_the_tray_and_primitives_rest_on_the_table(ask, engine):
    r, sols = ask(f'''create_scenario(S),
        add_to_scenario(S, [kitchen_env, mug1, tray1,
            entity(box1, rigid_object, _{{shape: box, size_x: 0.05, size_y: 0.05, size_z: 0.05,
                                          mass: 0.1, pose: _{{xyz: [0.1, 0.3, 0.745]}}}}),
            entity(can1, rigid_object, _{{shape: cylinder, radius: 0.03, height: 0.1,
                                          mass: 0.3, pose: _{{xyz: [0.1, -0.3, 0.77]}}}}),
            entity(ball1, rigid_object, _{{shape: sphere, radius: 0.02, mass: 0.05,
                                           friction: 1.0, rolling_friction: 0.01,
                                           pose: _{{xyz: [-0.4, -0.3, 0.74]}}}})]),
        make_projection(S, wait, [(_, duration, [0.5])], {on(engine)}, TL),
        findall(O, ( member(O, [mug1, tray1, box1, can1, ball1]),
                     holds(on(O, table1), interval(_, End), TL), End >= 0.45 ), On),
        findall(E, occurs(E, _, TL), Events)''')
    assert r.ok, r.message
    (s,) = sols
    assert s['On'] == ['mug1', 'tray1', 'box1', 'can1', 'ball1']
    assert s['Events'] == []


@pytest.mark.parametrize('engine', ENGINES)
def test_a_kb_file_and_an_asset_directory_of_ones_own(ask, own_files, engine):
    r, sols = ask(f'''scenario_entity(cube_on_table, cube1, E),
        get_dict(properties, E, P), get_dict(file, P, F),
        make_projection(cube_on_table, wait, [(_, duration, [0.3])], {on(engine)}, TL),
        ( holds(on(cube1, table1), _, TL) -> On = yes ; On = no )''')
    assert r.ok, r.message
    (s,) = sols
    assert s['F'] == {'string': str(own_files / 'models' / 'cube.obj')}
    assert s['On'] == 'yes'


def heights(bag) -> list[float]:
    """The heights of cube1's shape in the bag's markers, each message's."""
    from projection_server.bags.reader import read_bag
    from projection_server.bags.schema import TOPICS

    return [m.scale.z for _, _, msg in read_bag(bag, [TOPICS['markers']])
            for m in msg.markers if m.header.frame_id == 'cube1']


@pytest.mark.parametrize('engine', ENGINES)
def test_an_edited_mesh_is_projected_anew(ask, own_files, engine):
    # A warm worker keeps what it built of a scenario: the edited block must not be the cube.
    query = f'simulate(cube_on_table, wait, [(_, duration, [0.2])], {on(engine)}, Log)'
    cube = own_files / 'models' / 'cube.obj'
    cube.write_text(CUBE)
    try:
        r1, (s1,) = ask(query)
        r2, (s2,) = ask(query)
        cube.write_text(block(0.12))
        r3, (s3,) = ask(query)
    finally:
        cube.write_text(CUBE)
    assert r1.ok and r2.ok and r3.ok, r3.message
    assert s1['Log'] == s2['Log'] != s3['Log']
    first, edited = heights(s1['Log']), heights(s3['Log'])
    assert first and all(abs(h - 0.06) < 1e-6 for h in first), first
    assert edited and all(abs(h - 0.12) < 1e-6 for h in edited), edited


def entity(file: str, shape: str = 'mesh') -> str:
    return (f'create_scenario(S), add_to_scenario(S, entity(thing1, rigid_object, '
            f'_{{shape: {shape}, file: {json.dumps(file)}, mass: 0.1}}))')


@pytest.mark.parametrize('file, shape, kind, words', [
    ('../secret.obj', 'mesh', 'permission_error', 'outside the asset directories'),
    ('{root}/secret.obj', 'mesh', 'permission_error', 'outside the asset directories'),
    ('link.obj', 'mesh', 'permission_error', 'outside the asset directories'),
    ('none.obj', 'mesh', 'existence_error', 'no such file'),
    ('holes.obj', 'mesh', 'domain_error', 'names a vertex that does not exist'),
    ('nolink.urdf', 'urdf', 'domain_error', 'has no <link>'),
])
def test_a_bad_model_file_is_a_clear_error_and_the_node_serves_on(ask, own_files, file,
                                                                    shape, kind, words):
    file = file.format(root=own_files)
    r, _ = ask(entity(file, shape))
    assert not r.ok
    assert r.error_kind == kind, r.message
    assert words in r.message and os.path.basename(file) in r.message
    serves_on(ask)


def test_a_file_changed_to_a_bad_one_is_refused(ask):
    r, _ = ask('''create_scenario(S), add_to_scenario(S, cube1),
        scenario_set_property(S, cube1, file, "../secret.obj")''')
    assert r.error_kind == 'permission_error', r.message
    serves_on(ask)


@pytest.mark.parametrize('properties, words', [
    ('shape: cone, radius: 0.1, mass: 0.1', "unknown shape 'cone'"),
    ('shape: box, size_x: 0.1, size_y: 0.1, mass: 0.1', 'a box needs size_z'),
    ('shape: sphere, radius: 0.05, height: 0.1, mass: 0.1',
     'height is not a property of a sphere'),
])
def test_a_bad_shape_is_a_clear_error_and_the_node_serves_on(ask, properties, words):
    r, _ = ask(f'''create_scenario(S), add_to_scenario(S, [kitchen_env,
        entity(thing1, rigid_object, _{{{properties}, pose: _{{xyz: [0, 0.3, 0.8]}}}})]),
        make_projection(S, wait, [(_, duration, [0.2])], _)''')
    assert not r.ok
    assert r.error_kind == 'projection_error' and 'invalid_scenario' in r.message
    assert words in r.message, r.message
    serves_on(ask)


@pytest.mark.parametrize('goal', [
    'set_model_directories(["/"])',
    'model_files:set_model_directories(["/"])',
    'assertz(model_files:directories(["/"]))',
    "py_call('projection_server.assets':configure([\"/\"]), _)",
])
def test_a_query_cannot_change_the_asset_directories(ask, goal):
    r, _ = ask(goal)
    assert not r.ok and r.error_kind in ('permission_error', 'existence_error'), r.message
    r, _ = ask(entity('/etc/hostname.obj'))
    assert r.error_kind == 'permission_error'
    serves_on(ask)


@pytest.mark.parametrize('params, words', [
    ({'asset_paths': ['/nonexistent/models']}, '/nonexistent/models'),
    ({'kb_files': ['/nonexistent/my.ttl']}, '/nonexistent/my.ttl'),
])
def test_a_missing_asset_directory_or_kb_file_stops_the_node_with_a_clear_message(
        tmp_path, rclpy_context, params, words):
    from projection_server.client.launcher import node_command, NodeProcess
    log = tmp_path / 'node.log'
    with NodeProcess(node_command('bad_files', {**params, 'bag_dir': str(tmp_path / 'bags')}),
                     log) as proc:
        deadline = time.monotonic() + 60
        while proc.running:
            assert time.monotonic() < deadline, 'the node did not refuse to start'
            time.sleep(0.2)
    assert proc.returncode == 1
    assert words in log.read_text()
