"""Key frames of a projection, rendered from its bag: now :mod:`projection_server.render`,
re-exported here for the reproduction's users."""

from __future__ import annotations

from projection_server.render import (BagScene, BROKEN_COLOR, key_times, RenderError,
                                      render_frame, render_strip, save_png)

__all__ = [
    'BROKEN_COLOR',
    'BagScene',
    'RenderError',
    'key_times',
    'render_frame',
    'render_strip',
    'save_png',
]
