"""``projection_render BAG [--out DIR]``: key frames and a timeline chart of any bag."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
import sys
import time
from typing import TYPE_CHECKING

from projection_server.render.bag import default_out, render_bag
from projection_server.render.scene import RenderError

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = ['main']

PROG = 'projection_render'


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Render a projection's bag: key frames at its timeline's events (every "
                    'robot drawn with its meshes), a strip of them and a chart of the '
                    'timeline.')
    parser.add_argument('bag', type=Path, help="the projection's bag (a directory)")
    parser.add_argument('--out', type=Path, default=None, metavar='DIR',
                        help='directory for the PNG files (default: ./render/<bag name>)')
    parser.add_argument('--size', type=_size, default=(640, 480), metavar='WxH',
                        help='frame size in pixels (default: 640x480)')
    parser.add_argument('--target', default=None, metavar='ENTITY',
                        help='look at this entity (default: the centre of what moves)')
    parser.add_argument('--distance', type=float, default=None, metavar='M',
                        help="the camera's distance (default: 0.45 m from a target, else "
                             'all that moves in view)')
    parser.add_argument('--yaw', type=float, default=-30.0, help='camera yaw in degrees')
    parser.add_argument('--pitch', type=float, default=-20.0, help='camera pitch in degrees')
    parser.add_argument('--frames', type=int, default=10, metavar='N',
                        help='at most N key frames (default: 10)')
    parser.add_argument('--no-strip', action='store_true', help='no strip of the frames')
    parser.add_argument('--assets', action='append', default=[], metavar='DIR',
                        help="also look for robots' meshes here (repeatable)")
    args = parser.parse_args(argv)
    if args.frames < 2:
        parser.error('--frames must be at least 2')
    logging.basicConfig(format=f'{PROG}: warning: %(message)s', level=logging.WARNING)
    start = time.monotonic()
    try:
        paths = render_bag(args.bag, args.out, width=args.size[0], height=args.size[1],
                           target=args.target, distance=args.distance, yaw=args.yaw,
                           pitch=args.pitch, max_frames=args.frames, strip=not args.no_strip,
                           assets=args.assets)
    except RenderError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 1
    out = args.out if args.out is not None else default_out(args.bag)
    print(f'{len(paths)} files in {out} ({time.monotonic() - start:.1f} s)')
    for path in paths:
        print(f'  {path.name}')
    return 0


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split('x'))
    except ValueError:
        raise argparse.ArgumentTypeError(f'not WxH: {text!r}') from None
    if not (16 <= width <= 4096 and 16 <= height <= 4096):
        raise argparse.ArgumentTypeError(f'{text}: each side from 16 to 4096 pixels')
    return width, height


if __name__ == '__main__':
    sys.exit(main())
