"""Model files resolve only inside the asset directories, and only well formed ones do;
a job checks its files again and its cache key holds their content."""

from __future__ import annotations

import os
import struct

import pytest

from projection_server import assets
from projection_server.errors import ProjectionError
from projection_server.settings import load_settings
from projection_server.simulation import Job

TETRAHEDRON = 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n'


@pytest.fixture
def tree(tmp_path):
    """``models/`` (an asset directory) with a few files, and ``secret.obj`` beside it."""
    models = tmp_path / 'models'
    (models / 'sub').mkdir(parents=True)
    (models / 'tetra.obj').write_text(TETRAHEDRON)
    (models / 'sub' / 'part.obj').write_text(TETRAHEDRON)
    (models / 'thing.urdf').write_text(
        '<robot name="thing"><link name="base"><collision><geometry>'
        '<mesh filename="sub/part.obj"/></geometry></collision></link></robot>')
    (tmp_path / 'secret.obj').write_text(TETRAHEDRON)
    os.symlink(tmp_path / 'secret.obj', models / 'link.obj')
    return models


def status(path, models):
    return assets.resolve(path, [str(models)])[0]


def test_a_relative_path_resolves_in_the_first_directory_that_has_it(tmp_path, tree):
    other = tmp_path / 'other'
    other.mkdir()
    (other / 'tetra.obj').write_text(TETRAHEDRON)
    (other / 'only.obj').write_text(TETRAHEDRON)
    dirs = [str(tree), str(other)]
    assert assets.resolve('tetra.obj', dirs) == ['ok', str(tree / 'tetra.obj'), '']
    assert assets.resolve('only.obj', dirs) == ['ok', str(other / 'only.obj'), '']


def test_an_absolute_path_inside_resolves_to_itself(tree):
    assert assets.resolve(str(tree / 'sub' / '..' / 'tetra.obj'), [str(tree)])[1] == str(
        tree / 'tetra.obj')


@pytest.mark.parametrize('path', ['../secret.obj', 'sub/../../secret.obj', 'link.obj'])
def test_a_path_that_leads_outside_is_refused(path, tree):
    assert status(path, tree) == 'outside'


def test_an_absolute_path_outside_is_refused_whether_or_not_it_exists(tree):
    assert status(str(tree.parent / 'secret.obj'), tree) == 'outside'
    assert status('/etc/none.obj', tree) == 'outside'


def test_a_missing_file_is_missing(tree):
    assert status('none.obj', tree) == 'missing'
    assert status('sub', tree) == 'missing'


def test_another_file_type_is_refused(tree):
    (tree / 'notes.txt').write_text('hello')
    assert status('notes.txt', tree) == 'format'


@pytest.mark.parametrize('text, what', [
    ('v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n', 'names a vertex that does not exist'),
    ('v 0 0 0\nv 1 0 0\n', 'no faces'),
    ('f 1 2 3\n', 'no vertices'),
    ('v 0 0 zero\nf 1 1 1\n', 'a vertex needs three numbers'),
    ('v 0 0 0\nv 1 0 0\nf 1 2\n', 'a face needs three vertices'),
])
def test_a_malformed_obj_says_what_is_wrong(tree, text, what):
    (tree / 'bad.obj').write_text(text)
    result = assets.resolve('bad.obj', [str(tree)])
    assert result[:2] == ['malformed', 'obj'] and what in result[2]


def test_an_obj_may_count_its_vertices_back(tree):
    (tree / 'relative.obj').write_text('v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n')
    assert status('relative.obj', tree) == 'ok'
    assert assets.read_mesh(str(tree / 'relative.obj')).triangles == [(0, 1, 2)]


@pytest.mark.parametrize('text, what', [
    ('<robot name="x"><link name="a">', 'not well formed XML'),
    ('<model name="x"><link name="a"/></model>', 'not <robot>'),
    ('<robot name="x"/>', 'has no <link>'),
    ('<robot name="x"><link name="a"><visual><geometry><mesh filename="none.obj"/>'
     '</geometry></visual></link></robot>', 'does not exist'),
    ('<robot name="x"><link name="a"><visual><geometry><mesh filename="../secret.obj"/>'
     '</geometry></visual></link></robot>', 'outside the asset directories'),
])
def test_a_malformed_urdf_says_what_is_wrong(tree, text, what):
    (tree / 'bad.urdf').write_text(text)
    result = assets.resolve('bad.urdf', [str(tree)])
    assert result[:2] == ['malformed', 'urdf'] and what in result[2]


def test_a_urdf_naming_a_malformed_mesh_is_malformed(tree):
    (tree / 'sub' / 'part.obj').write_text('v 0 0 0\n')
    result = assets.resolve('thing.urdf', [str(tree)])
    assert result[0] == 'malformed' and 'part.obj' in result[2]


def test_an_obj_naming_a_material_library_outside_is_malformed(tree):
    (tree / 'mtl.obj').write_text('mtllib ../../etc/passwd\n' + TETRAHEDRON)
    assert status('mtl.obj', tree) == 'malformed'


def _binary_stl(triangles: int, extra: bytes = b'') -> bytes:
    data = b'\0' * 80 + struct.pack('<I', triangles)
    for _ in range(triangles):
        data += struct.pack('<12fH', 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0)
    return data + extra


def test_stl_binary_and_ascii(tree):
    (tree / 'b.stl').write_bytes(_binary_stl(2))
    (tree / 'short.stl').write_bytes(_binary_stl(2, b'xx'))
    (tree / 'a.stl').write_text('solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n'
                                'vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n')
    assert status('b.stl', tree) == 'ok'
    assert len(assets.read_mesh(str(tree / 'b.stl')).triangles) == 2
    assert status('a.stl', tree) == 'ok'
    assert status('short.stl', tree) == 'malformed'


SDF_PART = ('<sdf version="1.6"><model name="x"><link name="a"><collision name="c"><geometry>'
            '<mesh><uri>{}</uri></mesh></geometry></collision></link></model></sdf>')


@pytest.mark.parametrize('uri', ['sub/part.obj', '/sub/part.obj', 'model://sub/part.obj'])
def test_an_sdfs_mesh_resolves_beside_it_with_or_without_a_leading_slash(tree, uri):
    (tree / 'arm.sdf').write_text(SDF_PART.format(uri))
    assert assets.resolve('arm.sdf', [str(tree)]) == ['ok', str(tree / 'arm.sdf'), '']
    before = assets.digest(str(tree / 'arm.sdf'), [str(tree)])
    (tree / 'sub' / 'part.obj').write_text(TETRAHEDRON + 'v 2 2 2\n')
    assert assets.digest(str(tree / 'arm.sdf'), [str(tree)]) != before


@pytest.mark.parametrize('text, what', [
    ('<robot name="x"><link name="a"/></robot>', 'not <sdf>'),
    ('<sdf version="1.6"><model name="x"/></sdf>', 'no <model> with a <link>'),
    (SDF_PART.format('../secret.obj'), 'outside the asset directories'),
    (SDF_PART.format('none.stl'), 'does not exist'),
])
def test_a_malformed_sdf_says_what_is_wrong(tree, text, what):
    (tree / 'bad.sdf').write_text(text)
    result = assets.resolve('bad.sdf', [str(tree)])
    assert result[:2] == ['malformed', 'sdf'] and what in result[2], result


def test_the_kuka_with_its_gripper_in_pybullet_data_is_a_well_formed_sdf():
    dirs = assets.default_directories()
    assert assets.resolve('kuka_iiwa/kuka_with_gripper2.sdf', dirs)[0] == 'ok'


def test_the_package_assets_pybullet_data_and_received_descriptions_are_asset_directories():
    import pybullet_data

    dirs = assets.default_directories()
    assert dirs[0] == str(assets.PACKAGE_ASSETS)
    assert dirs[-2] == os.path.realpath(pybullet_data.getDataPath())
    assert dirs[-1] == os.path.realpath(assets.descriptions_dir())
    assert assets.resolve('objects/mug.urdf', dirs)[0] == 'ok'
    assert assets.resolve('glass.obj', dirs)[0] == 'ok'


def test_configured_directories_come_between_the_packages_and_pybullet_data(tree):
    try:
        dirs = assets.configure([str(tree)])
        assert dirs[1] == str(tree) and assets.directories() == dirs
        with pytest.raises(ValueError):
            assets.configure([str(tree / 'none')])
    finally:
        assets.configure([])


def test_a_digest_changes_with_the_content_of_a_urdfs_mesh(tree):
    urdf = str(tree / 'thing.urdf')
    before = assets.digest(urdf, [str(tree)])
    (tree / 'sub' / 'part.obj').write_text(TETRAHEDRON + 'v 2 2 2\n')
    assert assets.digest(urdf, [str(tree)]) != before


def _scenario(file: str) -> dict:
    return {'name': 's', 'entities': [
        {'name': 'thing1', 'class': 'rigid_object', 'pose': {'xyz': [0, 0, 1]},
         'properties': {'shape': 'mesh', 'file': file, 'mass': 0.1}}]}


def test_a_jobs_key_holds_the_content_of_its_model_files(tree):
    try:
        assets.configure([str(tree)])
        path = str(tree / 'tetra.obj')
        job = Job.checked(_scenario(path), 'wait', {'duration': 0.5})
        assert job.files == {path: assets.digest(path)}
        settings = load_settings()
        key = job.key(settings)
        (tree / 'tetra.obj').write_text(TETRAHEDRON + '# edited\n')
        assert Job.checked(_scenario(path), 'wait', {'duration': 0.5}).key(settings) != key
    finally:
        assets.configure([])


@pytest.mark.parametrize('path', ['tetra.obj', '{tree}/../secret.obj', '{tree}/link.obj',
                                  '{tree}/none.obj', '{tree}/sub'])
def test_a_job_takes_only_absolute_files_inside_the_asset_directories(tree, path):
    try:
        assets.configure([str(tree)])
        with pytest.raises(ProjectionError) as info:
            Job.checked(_scenario(path.format(tree=tree)), 'wait', {'duration': 0.5})
        assert info.value.kind == 'invalid_scenario'
    finally:
        assets.configure([])
