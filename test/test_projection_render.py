"""``projection_render``: key frames and a timeline chart of a Panda projection's bag, made
through the real node; the arm is drawn where its links stand."""

from __future__ import annotations

import json
from pathlib import Path
import shutil
import subprocess

import numpy as np
from projection_interfaces.srv import PrologQuery
import pytest

Q = PrologQuery.Request
SIZE = (320, 240)
PANDA_PLAN = '''create_scenario(S), add_to_scenario(S, [kitchen_env, panda_robot, egg1]),
    make_projection(S, plan([move_to(egg1, [0, 0, 0.10], [orientation(top), speed(0.5)]),
                             move_to(egg1, [0, 0, 0], [speed(0.1)]), close_gripper(5),
                             wait(0.2), move_by([0, 0, 0.1]), wait(0.3)]), [], TL),
    timeline_property(TL, meta(Meta)), get_dict(bag, Meta, Bag)'''


@pytest.fixture(scope='module')
def panda_bag(call) -> Path:
    r = call(PrologQuery, 'query', Q(mode=Q.ONCE, query=PANDA_PLAN, timeout=120.0),
             timeout=300.0)
    assert r.ok, (r.error_kind, r.message)
    bag = json.loads(r.solutions[0])['Bag']
    return Path(bag['string'] if isinstance(bag, dict) else bag)


@pytest.fixture(scope='module')
def command(panda_bag, tmp_path_factory):
    """``projection_render BAG --out DIR``: the finished process and DIR."""
    out = tmp_path_factory.mktemp('render') / 'panda'
    proc = subprocess.run([_script(), str(panda_bag), '--out', str(out),
                           '--size', f'{SIZE[0]}x{SIZE[1]}'],
                          capture_output=True, text=True, timeout=300)
    return proc, out


@pytest.fixture(scope='module')
def scene(panda_bag):
    from projection_server.render import BagScene
    return BagScene.load(panda_bag)


def _script() -> str:
    path = shutil.which('projection_render')
    assert path is not None, 'projection_render is not installed (make setup)'
    return path


def _png(path: Path) -> np.ndarray:
    import matplotlib.image
    return (matplotlib.image.imread(path)[:, :, :3] * 255).astype(np.uint8)


def test_the_command_writes_key_frames_at_the_events_a_strip_and_a_chart(command):
    proc, out = command
    assert proc.returncode == 0, proc.stderr
    names = sorted(p.name for p in out.iterdir())
    frames = [n for n in names if n.startswith('frame_')]
    assert frames[0].startswith('frame_00_0.00s_start') and frames[-1].endswith('_end.png')
    assert any('grasp_egg1' in n for n in frames), frames
    assert 'strip.png' in names and 'timeline.png' in names
    assert _png(out / frames[0]).shape == (SIZE[1], SIZE[0], 3)
    for name in names:
        assert (out / name).read_bytes().startswith(b'\x89PNG\r\n\x1a\n')


def test_render_bag_returns_the_files_it_wrote_frames_first(panda_bag, tmp_path):
    from projection_server.render import render_bag
    paths = render_bag(panda_bag, tmp_path / 'out', width=160, height=120, max_frames=4)
    assert [p.name for p in paths[-2:]] == ['strip.png', 'timeline.png']
    assert len(paths) == 6 and all(p.is_file() for p in paths)
    assert paths[0].name.startswith('frame_00_0.00s_start')


def _grey(window: np.ndarray) -> np.ndarray:
    """Pixels of the Panda's colours: its white and dark grey links are unsaturated,
    shaded from near black to white."""
    pixels = window.reshape(-1, 3).astype(int)
    return (pixels.max(axis=1) - pixels.min(axis=1)) < 18


def test_a_frame_shows_the_arm_in_its_colours_where_its_links_stand(scene):
    from projection_server.render import Renderer
    (robot,) = scene.robots
    assert robot.name == 'panda_robot' and not robot.missing
    links = sorted({v.frame for v in robot.visuals if v.kind == 'mesh'})
    assert len(links) >= 8, links
    t = scene.duration / 2
    with Renderer(scene) as renderer:
        camera = renderer.camera(distance=None, yaw=-30.0, pitch=-20.0, lift=-0.1,
                                 width=SIZE[0], height=SIZE[1])
        image = renderer.frame(t, camera)
        without = renderer.frame(t, camera, hide={robot.name})
    shown = 0
    for link in links:
        col, row = (int(round(v)) for v in camera.pixel(scene.pose(link, t)[0]))
        assert 3 <= col < SIZE[0] - 3 and 3 <= row < SIZE[1] - 3, (link, col, row)
        window = (slice(row - 3, row + 4), slice(col - 3, col + 4))
        drawn = np.abs(image[window].astype(int) - without[window]).max(axis=2) > 20
        # where the arm stands: the picture changed and is the arm's colour
        if np.mean(drawn & _grey(image[window]).reshape(7, 7)) > 0.5:
            shown += 1
    assert shown >= len(links) - 1, f'{shown} of {len(links)} links drawn'


def test_the_chart_has_a_row_per_object_of_the_timeline(panda_bag, tmp_path):
    from projection_server.render import timeline_chart, timeline_of_bag
    timeline = timeline_of_bag(panda_bag)
    named = {a for _, args, _, _ in timeline['fluents'] + timeline['events']
             for a in args if isinstance(a, str)}
    rows = timeline_chart(timeline, tmp_path / 'timeline.png')
    assert rows == sorted(named) and {'egg1', 'panda_robot'} <= set(rows)
    image = _png(tmp_path / 'timeline.png')
    coloured = (image.max(axis=2).astype(int) - image.min(axis=2)) > 60   # bars, marks
    assert image.std() > 20 and coloured.sum() > 1000


def _fails(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([_script(), *args], capture_output=True, text=True, timeout=120)


def test_a_missing_bag_is_a_one_line_error(tmp_path):
    proc = _fails(str(tmp_path / 'no_such_bag'))
    assert proc.returncode == 1
    assert proc.stderr.strip().count('\n') == 0 and 'Traceback' not in proc.stderr
    assert proc.stderr.startswith('projection_render: error:') and 'no_such_bag' in proc.stderr


def test_a_file_that_is_not_a_bag_is_a_one_line_error(tmp_path):
    (tmp_path / 'notes.txt').write_text('not a bag\n')
    proc = _fails(str(tmp_path / 'notes.txt'))
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.strip().count('\n') == 0 and 'Traceback' not in proc.stderr


def test_bad_arguments_exit_with_status_2(panda_bag):
    proc = _fails(str(panda_bag), '--size', 'big')
    assert proc.returncode == 2 and 'Traceback' not in proc.stderr


def test_a_mesh_not_found_is_drawn_as_a_box_with_one_warning(caplog):
    from projection_server.render import parse_robot
    urdf = '''<robot name="r"><material name="blue"><color rgba="0 0 1 1"/></material>
      <link name="r"><visual><geometry><mesh filename="package://gone/a.obj"/></geometry>
        </visual></link>
      <link name="r/l1"><visual><geometry><mesh filename="package://gone/a.obj"/></geometry>
        </visual><visual><origin xyz="0 0 0.1"/><geometry><box size="0.1 0.2 0.3"/>
        </geometry><material name="blue"/></visual></link>
      <link name="r/l2"><visual><geometry>
        <mesh filename="file:///elsewhere/franka_panda/meshes/visual/link1.obj"/>
        </geometry></visual></link>
      <joint name="j1" type="fixed"><parent link="r"/><child link="r/l1"/></joint>
      <joint name="j2" type="fixed"><parent link="r/l1"/><child link="r/l2"/></joint>
    </robot>'''
    with caplog.at_level('WARNING', logger='projection_server.render'):
        robot = parse_robot(urdf)
    assert robot.name == 'r' and robot.missing == ('package://gone/a.obj',)
    assert len(caplog.records) == 1
    kinds = [(v.frame, v.kind) for v in robot.visuals]
    assert kinds == [('r', 'box'), ('r/l1', 'box'), ('r/l1', 'box'), ('r/l2', 'mesh')]
    assert robot.visuals[2].rgba == (0.0, 0.0, 1.0, 1.0) and robot.visuals[2].xyz[2] == 0.1
    # a bag made on another machine: the Panda's mesh is found in pybullet_data
    assert robot.visuals[3].mesh.endswith('franka_panda/meshes/visual/link1.obj')


TWO_ROBOTS = '''<robot name="{name}">
  <link name="{name}"><visual><geometry><box size="0.2 0.2 0.2"/></geometry>
    <material name="c"><color rgba="{rgba}"/></material></visual></link>
  <link name="{name}/top"><visual><geometry><{top}/></geometry>
    <material name="c"/></visual></link>
  <joint name="j" type="fixed"><parent link="{name}"/><child link="{name}/top"/></joint>
</robot>'''


def test_every_robot_of_a_scene_is_drawn_in_its_colours_at_its_links_poses():
    from projection_server.render import BagScene, parse_robot, Renderer
    from projection_server.render.scene import Track

    def track(parent, xyz):   # two samples: a frame that moves, in the camera's focus
        return Track(parent, [0.0, 1.0], np.array([xyz, xyz], dtype=float),
                     np.array([[0, 0, 0, 1.0]] * 2))
    robots = [parse_robot(TWO_ROBOTS.format(name='red', rgba='1 0 0 1',
                                            top='sphere radius="0.1"')),
              parse_robot(TWO_ROBOTS.format(name='blue', rgba='0 0 1 1',
                                            top='cylinder radius="0.1" length="0.2"'))]
    tracks = {'red': track('world', (0, -0.4, 0.5)), 'red/top': track('red', (0, 0, 0.3)),
              'blue': track('world', (0, 0.4, 0.5)), 'blue/top': track('blue', (0, 0, 0.3))}
    scene = BagScene(tracks, [], [], 1.0, robots)
    with Renderer(scene) as renderer:
        camera = renderer.camera(distance=2.5, yaw=90.0, pitch=-10.0, lift=0.0,
                                 width=SIZE[0], height=SIZE[1])
        image = renderer.frame(0.5, camera).astype(int)
    for frame, channel in (('red', 0), ('red/top', 0), ('blue', 2), ('blue/top', 2)):
        col, row = (int(round(v)) for v in camera.pixel(scene.pose(frame, 0.5)[0]))
        pixel = image[row, col]
        assert pixel[channel] > 80 and pixel[channel] > 2 * np.delete(pixel, channel).max(), (
            frame, pixel)
