"""The transform buffer answers as tf2 does: chains through a common ancestor, at a time
(interpolated) or at the latest common time, static links without age, and named errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from projection_server.world.transforms import Transform, TransformBuffer, TransformError

S = 1_000_000_000
YAW90 = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))
ID = (0.0, 0.0, 0.0, 1.0)


def _buffer() -> TransformBuffer:
    b = TransformBuffer()
    b.add(Transform('map', 'base', (1.0, 0.0, 0.0), YAW90, None))          # static
    b.add(Transform('base', 'hand', (0.0, 1.0, 0.0), ID, 10 * S))
    b.add(Transform('base', 'hand', (0.0, 3.0, 0.0), ID, 12 * S))
    b.add(Transform('map', 'egg', (0.5, 0.5, 0.0), ID, 11 * S))
    return b


def test_a_chain_composes_through_the_common_ancestor():
    (xyz, q), stamp = _buffer().lookup('map', 'hand', 12 * S)
    # base is turned 90 deg about z: its +y is the map's -x.
    assert np.allclose(xyz, [1.0 - 3.0, 0.0, 0.0]) and np.allclose(q, YAW90)
    assert stamp == 12 * S


def test_a_time_between_two_transforms_is_interpolated():
    (xyz, _), _ = _buffer().lookup('base', 'hand', 11 * S)
    assert np.allclose(xyz, [0.0, 2.0, 0.0])


def test_the_latest_is_the_newest_time_every_link_has():
    b = _buffer()
    assert b.lookup('map', 'hand')[1] == 12 * S
    # egg (newest 11 s) and hand (newest 12 s): their common latest is 11 s.
    (xyz, _), stamp = b.lookup('egg', 'hand')
    assert stamp == 11 * S and np.allclose(xyz, [1.0 - 2.0 - 0.5, -0.5, 0.0])


def test_static_links_alone_have_no_time():
    assert _buffer().lookup('map', 'base')[1] is None


def test_an_unknown_frame_is_named_with_the_known_ones():
    with pytest.raises(TransformError) as e:
        _buffer().lookup('map', 'cup')
    assert e.value.kind == 'unknown' and e.value.frame == 'cup' and 'egg' in e.value.message


def test_frames_of_two_trees_are_unconnected():
    b = _buffer()
    b.add(Transform('odom', 'cup', (0.0, 0.0, 0.0), ID, 11 * S))
    with pytest.raises(TransformError) as e:
        b.lookup('map', 'cup')
    assert e.value.kind == 'unconnected'


def test_a_time_outside_the_kept_transforms_is_an_extrapolation():
    with pytest.raises(TransformError) as e:
        _buffer().lookup('base', 'hand', 13 * S)
    assert e.value.kind == 'extrapolation'


def test_transforms_older_than_the_cache_time_are_dropped():
    b = TransformBuffer(cache_time=10.0)
    for t in range(0, 30):
        b.add(Transform('map', 'egg', (float(t), 0.0, 0.0), ID, t * S))
    with pytest.raises(TransformError):
        b.lookup('map', 'egg', 15 * S)
    assert np.allclose(b.lookup('map', 'egg', 20 * S)[0][0], [20.0, 0.0, 0.0])
