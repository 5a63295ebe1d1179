"""The timeline's arithmetic: frames composed for all samples at once are those composed
one sample at a time, to the last bit."""

from __future__ import annotations

import numpy as np

from projection_server.timeline.samples import _compose_all, Poses


def _message(rng, layout):
    frames = []
    for parent, child in layout:
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        frames.append((parent, child, tuple(float(x) for x in rng.normal(size=3)),
                       tuple(float(x) for x in q)))
    return frames


def test_frames_composed_for_all_samples_are_those_of_each_sample():
    rng = np.random.default_rng(11)
    # A robot's chain (parents first), a body in the world, and a frame whose parent comes
    # after it in the message (so it hangs off the world).
    layout = [('world', 'robot'), ('robot', 'robot/a'), ('robot/a', 'robot/b'),
              ('robot/a', 'robot/c'), ('world', 'egg'), ('robot/d', 'robot/e'),
              ('robot', 'robot/d')]
    messages = [_message(rng, layout) for _ in range(60)]
    batched, single = [], []
    for message in messages:
        for poses, out in ((Poses(), batched), (Poses(), single)):
            poses.add(message)
            out.append(poses)
    _compose_all(batched)
    assert all(entry[3] is not None for poses in batched for entry in poses._frames.values())
    for a, b in zip(batched, single):
        for (name, (p, r)), (name_b, (q, s)) in zip(a.items(), b.items()):
            assert name == name_b
            assert p.tobytes() == q.tobytes() and r.tobytes() == s.tobytes()
