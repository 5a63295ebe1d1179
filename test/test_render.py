"""Key frames rendered from a real projection's bag (which also shows that bags replay)."""

from __future__ import annotations

import numpy as np
import pytest

# The grasping scenario as the knowledge base describes it (scenario.pl, kitchen.ttl).
GRASPING = {
    'name': 'grasping',
    'entities': [
        {'name': 'kitchen_env', 'class': 'environment',
         'pose': {'xyz': [0.0, 0.0, 0.0], 'rpy': [0.0, 0.0, 0.0]},
         'properties': {'gravity': 9.81},
         'parts': [
             {'name': 'floor1', 'class': 'floor', 'parts': [],
              'pose': {'xyz': [0.0, 0.0, 0.0], 'rpy': [0.0, 0.0, 0.0]},
              'properties': {'shape': 'plane', 'mass': 0.0, 'friction': 0.6,
                             'restitution': 0.1}},
             {'name': 'table1', 'class': 'table', 'parts': [],
              'pose': {'xyz': [0.0, 0.0, 0.7], 'rpy': [0.0, 0.0, 0.0]},
              'properties': {'shape': 'box', 'size_x': 1.2, 'size_y': 0.8, 'size_z': 0.04,
                             'height': 0.72, 'mass': 0.0, 'friction': 0.6,
                             'restitution': 0.1}},
         ]},
        {'name': 'pr2_robot', 'class': 'robot',
         'pose': {'xyz': [-0.95, 0.0, 0.0], 'rpy': [0.0, 0.0, 0.0]},
         'properties': {'gripper': 'pr2_gripper', 'model': 'pr2', 'shape': 'none'},
         'parts': [
             {'name': 'pr2_gripper', 'class': 'gripper', 'parts': [],
              'pose': {'xyz': [-0.45, 0.0, 0.9], 'rpy': [0.0, 0.0, 0.0]},
              'properties': {'shape': 'urdf', 'urdf': 'pr2_gripper.urdf', 'friction': 1.0,
                             'max_force': 80.0, 'max_opening': 0.09, 'restitution': 0.0}},
         ]},
        {'name': 'egg1', 'class': 'egg', 'parts': [],
         'pose': {'xyz': [-0.3, 0.0, 0.742], 'rpy': [0.0, 0.0, 0.0]},
         'properties': {'shape': 'ellipsoid', 'length': 0.058, 'diameter': 0.044,
                        'mass': 0.06, 'friction': 0.35, 'restitution': 0.05,
                        'rolling_friction': 0.001, 'spinning_friction': 0.001,
                        'breaking_force': 10.0}},
    ],
}


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """A real projection's bag: grasping the egg with 11 N at its centre (it breaks)."""
    from projection_server import projection
    projection.shutdown()
    projection.configure(bag_dir=tmp_path_factory.mktemp('bags'))
    try:
        yield projection.simulate(GRASPING, 'grasp_object',
                                  {'force': 11.0, 'position': 0.0}, 60.0)
    finally:
        projection.shutdown()


@pytest.fixture(scope='module')
def scene(bag):
    from projection_server.reproduce.render import BagScene
    return BagScene.load(bag)


def _egg_pixels(image: np.ndarray, rgb: tuple[float, float, float]) -> int:
    """Pixels whose colour is the egg's, allowing for shading (same hue, some darkening)."""
    target = np.array(rgb) / max(rgb)
    pixels = image.reshape(-1, 3).astype(float)
    bright = pixels.max(axis=1)
    chroma = pixels / np.maximum(bright, 1.0)[:, None]
    close = np.abs(chroma - target).max(axis=1) < 0.03
    return int(np.count_nonzero(close & (bright > 60) & (pixels.min(axis=1) < 250)))


def test_the_bag_replays_the_egg_shape_and_its_motion(scene):
    shapes = {s.frame: s for s in scene.shapes_at(0.0)}
    assert 'egg1' in shapes and 'table1' in shapes
    assert shapes['egg1'].scale == pytest.approx((0.058, 0.044, 0.044))
    assert len(scene.tracks['egg1'].times) > 10
    assert scene.duration > 1.0


def test_a_frame_before_the_grasp_shows_the_egg_in_its_colour(scene, tmp_path):
    from projection_server.reproduce.render import render_frame, save_png
    egg = next(s for s in scene.shapes_at(0.0) if s.frame == 'egg1')
    image = render_frame(scene, 0.5, target='egg1', width=240, height=180)
    assert image.shape == (180, 240, 3)
    assert image.std() > 10                           # not one flat colour
    with_egg = _egg_pixels(image, egg.rgba[:3])
    without = _egg_pixels(render_frame(scene, 0.5, target='egg1', width=240, height=180,
                                       hide={'egg1'}), egg.rgba[:3])
    assert with_egg > 100 and without < with_egg / 10
    path = save_png(image, tmp_path / 'frame.png')
    assert path.read_bytes().startswith(b'\x89PNG\r\n\x1a\n')


def test_after_the_break_the_egg_is_drawn_broken(scene):
    from projection_server.reproduce.render import BROKEN_COLOR, render_frame
    assert 'egg1' in scene.broken_at(scene.duration)
    image = render_frame(scene, scene.duration, target='egg1', width=240, height=180)
    assert _egg_pixels(image, BROKEN_COLOR[:3]) > 20


def test_key_times_are_the_events_and_evenly_spaced_frames_where_there_are_none():
    from projection_server.reproduce.experiments import Event
    from projection_server.reproduce.render import key_times
    slip = Event('slip', 'slip(egg1)', 2.0, 2.0)
    grasp = Event('grasp', 'grasp(egg1)', 1.0, 1.0)
    assert key_times([slip, grasp], 4.0, minimum=3) == [
        (0.0, 'start'), (1.0, 'grasp(egg1)'), (2.0, 'slip(egg1)'), (4.0, 'end')]
    # A pour has no events: frames fill the longest gaps.
    assert [t for t, _ in key_times([], 4.0)] == [0.0, 1.0, 2.0, 4.0]
    assert key_times([], 4.0)[1] == (1.0, '')
    assert key_times([], 0.05) == [(0.0, 'start')]
