"""Pictures of any projection, from its bag alone: key frames and a chart of its timeline.

``projection_render BAG [--out DIR]`` (:mod:`.cli`) or :func:`render_bag` writes key frames
at the timeline's events, every robot drawn with its links' visual meshes at their ``/tf``
poses and the objects from their markers, a strip of them and a chart of the timeline.

Modules: :mod:`.scene` (a bag's shapes, robots and poses over time), :mod:`.robots` (links'
visuals from ``robot_description``, meshes found on this machine), :mod:`.shapes` (PyBullet
visual shapes), :mod:`.frames` (the renderer, its camera, key times, strips), :mod:`.chart`
(the timeline's chart), :mod:`.bag` (all pictures of one bag), :mod:`.cli`.

    >>> render_bag('bags/0f3a...', 'pictures')   # [Path('pictures/frame_00_0.00s_start.png'), ...]
"""

from __future__ import annotations

from projection_server.render.bag import default_out, render_bag, timeline_of_bag
from projection_server.render.chart import chart_rows, timeline_chart
from projection_server.render.frames import (BROKEN_COLOR, Camera, key_times, Renderer,
                                             render_frame, render_strip, save_png)
from projection_server.render.robots import LinkVisual, parse_robot, RobotModel
from projection_server.render.scene import BagScene, RenderError, Shape

__all__ = [
    'BROKEN_COLOR',
    'BagScene',
    'Camera',
    'LinkVisual',
    'RenderError',
    'Renderer',
    'RobotModel',
    'Shape',
    'chart_rows',
    'default_out',
    'key_times',
    'parse_robot',
    'render_bag',
    'render_frame',
    'render_strip',
    'save_png',
    'timeline_chart',
    'timeline_of_bag',
]
