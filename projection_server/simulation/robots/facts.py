"""The facts of a ``urdf`` robot, read off its model file: what a user needs to write its
``entity(Name, robot, _{model: urdf, ...})``.

``python -m projection_server.simulation.robots.facts FILE`` lists the model's joints (index,
name, type, limits, effort, the link it moves, its parent link, the joint it mimics). Given
the gripper's facts as well (``--tool-link``, ``--fingers``; ``--open``, ``--closed``,
``--pads`` if they are not the defaults), it measures the pads as the simulation will: the
gap between them closed, half open and open, and where they are closest half open, in
the tool link's frame: their midpoint is the ``tool_offset``, the line
between them the closing axis (y of the tool frame; if it is the link's x, ``tool_rpy: [0,
0, 1.5708]``). ``FILE`` is a path, or one relative to ``pybullet_data``.
"""

from __future__ import annotations

import argparse
import os
from typing import Any, Sequence

import numpy as np

__all__ = ['describe', 'main', 'measure']


def _path(file: str) -> str:
    import pybullet_data

    return file if os.path.exists(file) else os.path.join(pybullet_data.getDataPath(), file)


def _load(path: str) -> tuple[Any, int]:
    import pybullet

    from projection_server.simulation.physics import bound_client
    from projection_server.simulation.robots.kinematics import load_robot

    client = bound_client(pybullet.DIRECT)
    body = load_robot(client, path, (0, 0, 0), (0, 0, 0, 1))
    if body < 0:
        raise SystemExit(f'cannot load {path}')
    return client, body


def describe(client: Any, body: int, mimics: dict[str, tuple[str, float, float]]) -> str:
    """A table of the joints of ``body``."""
    kinds = {client.JOINT_REVOLUTE: 'revolute', client.JOINT_PRISMATIC: 'prismatic',
             client.JOINT_FIXED: 'fixed', client.JOINT_SPHERICAL: 'spherical'}
    rows = [f'{"#":>3} {"joint":28} {"type":9} {"lower":>8} {"upper":>8} {"effort":>7}  '
            f'{"moves link":24} {"parent link":24} mimics']
    for j in range(client.getNumJoints(body)):
        info = client.getJointInfo(body, j)
        name, parent = info[1].decode(), info[16]
        parent_name = (client.getBodyInfo(body)[0].decode() if parent < 0
                       else client.getJointInfo(body, parent)[12].decode())
        mimic = mimics.get(name)
        rows.append(f'{j:3} {name:28} {kinds.get(info[2], "?"):9} {info[8]:8.3f} '
                    f'{info[9]:8.3f} {info[10]:7.1f}  {info[12].decode():24} {parent_name:24} '
                    f'{"" if mimic is None else f"{mimic[0]} x{mimic[1]:g} {mimic[2]:+g}"}')
    return '\n'.join(rows)


def measure(client: Any, body: int, tool_link: str, fingers: Sequence[str],
            open_values: Sequence[float] | None, closed_values: Sequence[float] | None,
            pads: Sequence[str] | None, mimics: dict[str, tuple[str, float, float]]) -> str:
    """The pads' gap closed, half open and open, and where they are half open, in the
    tool link's frame."""
    from projection_server.simulation.robots.linkage import finger_values, gap

    joints = {client.getJointInfo(body, j)[1].decode(): j
              for j in range(client.getNumJoints(body))}
    links = {client.getJointInfo(body, j)[12].decode(): j for j in joints.values()}
    finger_ids = [joints[n] for n in fingers]
    infos = [client.getJointInfo(body, j) for j in finger_ids]
    limits = open_values is None or closed_values is None
    if limits:
        open_values, closed_values = [i[9] for i in infos], [i[8] for i in infos]
    if pads is None:
        pads = [i[12].decode() for i in infos]
    pad_ids = [links[n] for n in pads]
    coupled = {joints[c]: (joints[p], m, o) for c, (p, m, o) in mimics.items()
               if c in joints and p in joints}
    if limits:   # as the simulation takes them: open is where the pads are further apart
        ends = [gap(client, body, finger_values(finger_ids, open_values, closed_values, coupled,
                                                {}, u), pad_ids) for u in (0.0, 1.0)]
        if ends[1] < ends[0]:
            open_values, closed_values = closed_values, open_values
    lines = [f'finger_open {list(open_values)}, finger_closed {list(closed_values)}']
    for u, what in ((0.0, 'closed'), (0.5, 'half open'), (1.0, 'open')):
        values = finger_values(finger_ids, open_values, closed_values, coupled, {}, u)
        lines.append(f'gap {what:9}: {gap(client, body, values, pad_ids) * 1000:7.1f} mm')
    values = finger_values(finger_ids, open_values, closed_values, coupled, {}, 0.5)
    gap(client, body, values, pad_ids)
    state = client.getLinkState(body, links[tool_link], computeForwardKinematics=True)
    inverse = client.invertTransform(state[4], state[5])
    points = min((p for i, a in enumerate(pad_ids) for b in pad_ids[i + 1:]
                  for p in client.getClosestPoints(body, body, 1.0, a, b)),
                 key=lambda p: p[8])
    a = np.asarray(client.multiplyTransforms(*inverse, points[5], (0, 0, 0, 1))[0])
    b = np.asarray(client.multiplyTransforms(*inverse, points[6], (0, 0, 0, 1))[0])
    axis = (b - a) / max(np.linalg.norm(b - a), 1e-9)
    lines.append(f'pads half open, in {tool_link}\'s frame: midpoint (tool_offset) '
                 f'{np.round((a + b) / 2, 4).tolist()}, closing axis {np.round(axis, 3).tolist()}')
    return '\n'.join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    from projection_server.simulation.robots.urdf_arm import mimic_joints

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('file')
    parser.add_argument('--tool-link')
    parser.add_argument('--fingers', help='finger joints, comma separated')
    parser.add_argument('--open', help="the finger joints' values open, comma separated")
    parser.add_argument('--closed', help="the finger joints' values closed, comma separated")
    parser.add_argument('--pads', help='the pad links, comma separated')
    args = parser.parse_args(argv)
    path = _path(args.file)
    client, body = _load(path)
    mimics = mimic_joints(path) if path.lower().endswith('.urdf') else {}
    print(describe(client, body, mimics))
    if args.tool_link and args.fingers:
        split = (lambda text, kind: None if text is None
                 else [kind(v) for v in text.split(',')])
        print(measure(client, body, args.tool_link, split(args.fingers, str),
                      split(args.open, float), split(args.closed, float),
                      split(args.pads, str), mimics))
    client.disconnect()


if __name__ == '__main__':
    main()
