"""Every picture of one projection's bag: key frames at its timeline's events, a strip of
them, and a chart of the timeline (:func:`render_bag`)."""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import re
from typing import Any, TYPE_CHECKING

from projection_server.render.chart import term_text, timeline_chart
from projection_server.render.frames import key_times, Renderer, render_strip, save_png
from projection_server.render.scene import BagScene, RenderError

if TYPE_CHECKING:
    from collections.abc import Iterable

__all__ = ['default_out', 'render_bag', 'timeline_of_bag']


@dataclass(frozen=True)
class _Event:
    term: str
    start: float
    end: float


def default_out(bag: str | os.PathLike[str]) -> Path:
    """Where :func:`render_bag` writes without ``out``: ``./render/<the bag's name>``."""
    return Path('render') / Path(bag).resolve().name


def timeline_of_bag(bag: str | os.PathLike[str]) -> dict[str, Any]:
    """The timeline of the projection logged in ``bag`` (as its worker made it).

    Raises:
        RenderError: the bag cannot be read or is not a projection's.
    """
    from projection_server.errors import ProjectionError
    from projection_server.workers.run import translate_bag

    try:
        return translate_bag(bag)
    except ProjectionError as exc:
        raise RenderError(f'no timeline of {bag}: {exc.message}') from exc


def render_bag(bag: str | os.PathLike[str], out: str | os.PathLike[str] | None = None, *,
               width: int = 640, height: int = 480, target: str | None = None,
               distance: float | None = None, yaw: float = -30.0, pitch: float = -20.0,
               max_frames: int = 10, strip: bool = True,
               assets: Iterable[str | os.PathLike[str]] = ()) -> list[Path]:
    """Render the projection logged in ``bag`` into the directory ``out`` (made if missing;
    default :func:`default_out`); the paths written, frames first.

    Writes ``frame_NN_<t>s_<event>.png`` at the start, each event of the timeline
    (interval events at their middle; at most ``max_frames`` frames, see
    :func:`~projection_server.render.frames.key_times`) and the end; ``strip.png``, those
    side by side (unless ``strip`` is false); ``timeline.png``, the timeline's chart
    (:func:`~projection_server.render.chart.timeline_chart`). The camera looks at
    ``target`` (an entity's name) or at the centre of what moves, from ``distance`` metres
    (None: 0.45 m from a target, else far enough to see all that moves), turned by ``yaw``
    and ``pitch`` degrees.
    Robots' meshes are looked for in ``assets`` too.

    Raises:
        RenderError: the bag cannot be read, or is not a projection's.
    """
    scene = BagScene.load(bag, assets)
    timeline = timeline_of_bag(bag)
    out = Path(out) if out is not None else default_out(bag)
    out.mkdir(parents=True, exist_ok=True)
    events = [_Event(term_text(name, args), float(start), float(end))
              for name, args, start, end in timeline['events']]
    times = key_times(events, scene.duration, limit=max(2, max_frames))
    written: list[Path] = []
    images = []
    with Renderer(scene) as renderer:
        # Without a target the centre of what moves is high up the arm: look lower.
        camera = renderer.camera(target=target, distance=distance, yaw=yaw, pitch=pitch,
                                 lift=0.05 if target else -0.1, width=width, height=height)
        for index, (t, label) in enumerate(times):
            image = renderer.frame(t, camera)
            images.append(image)
            name = f'frame_{index:02d}_{t:.2f}s' + (f'_{_slug(label)}' if label else '')
            written.append(save_png(image, out / f'{name}.png'))
    if strip:
        written.append(render_strip(scene, times, out / 'strip.png', frames=images,
                                    caption=_caption(timeline)))
    timeline_chart(timeline, out / 'timeline.png', title=_caption(timeline))
    written.append(out / 'timeline.png')
    return written


def _slug(label: str) -> str:
    return re.sub(r'[^A-Za-z0-9_.-]+', '_', label).strip('_')[:60]


def _caption(timeline: dict[str, Any]) -> str:
    meta = timeline.get('meta', {})
    parts = [str(meta.get(key)) for key in ('scenario', 'program') if meta.get(key)]
    program = parts[-1] if parts else ''
    if len(program) > 60:   # a plan's whole text
        parts[-1] = program[:57] + '...'
    return ': '.join(parts)
