"""Physics: the named queries that the monitor's samples are made of."""

from __future__ import annotations

import numpy as np

from projection_server.simulation import load_settings
from projection_server.simulation.physics import Body, Fluid, Physics


def _point(rng, a, b, link_a=-1, link_b=-1):
    """A contact point as PyBullet's getContactPoints gives it, with random numbers."""
    unit = rng.normal(size=3)
    unit /= np.linalg.norm(unit)

    def vector():
        return tuple(float(x) for x in rng.normal(size=3))

    return (0, a, b, link_a, link_b, vector(), vector(), tuple(float(x) for x in unit),
            float(rng.normal()), float(abs(rng.normal())), float(rng.normal()), vector(),
            float(rng.normal()), vector())


def test_contacts_sum_a_link_pairs_points_as_a_loop_over_them_does():
    """Physics.contacts sums a pair's points with array arithmetic; its numbers must be
    those of the loop over the points it replaced, to the last bit."""
    physics = Physics(None, load_settings())
    for body_id, name in ((1, 'cup'), (2, 'maker')):
        physics.add_body(Body(name, 'thing', body_id, False, None, links={0: 'rim'}))
    physics.add_fluid(Fluid('batter', 0.006, [10, 11, 12]))
    for particle in (10, 11, 12):
        physics.add_body(Body(f'batter_{particle}', 'particle', particle, False, None,
                              group='batter'))
    rng = np.random.default_rng(3)
    points = [_point(rng, *pair) for pair in
              [(1, 10), (1, 11, 0), (2, 1), (1, 2, 0), (12, 1), (2, 12), (1, 10), (10, 11)]
              * 5]
    points.append(_point(rng, 1, 2, -1, 0)[:9] + (0.0,) + _point(rng, 1, 2)[10:])  # no force
    physics._contact_points = lambda: points
    expected = []
    groups = {}
    for point in points:
        a, b = physics.name_of(point[1]), physics.name_of(point[2])
        if a == b == 'batter':
            continue
        key_a = (a, physics.link_name(point[1], point[3]))
        key_b = (b, physics.link_name(point[2], point[4]))
        sign = 1.0 if key_a < key_b else -1.0
        key = (*key_a, *key_b) if sign > 0 else (*key_b, *key_a)
        groups.setdefault(key, []).append((point, sign))
    for key in sorted(groups):
        pts = groups[key]
        forces = np.array([p[9] for p, _ in pts])
        total = float(forces.sum())
        positions = np.array([(np.asarray(p[5]) + p[6]) / 2 for p, _ in pts])
        weights = forces / total if total > 0 else np.full(len(pts), 1 / len(pts))
        normal = sum(s * np.asarray(p[7]) * w for (p, s), w in zip(pts, weights))
        norm = np.linalg.norm(normal)
        friction = sum(s * (p[10] * np.asarray(p[11]) + p[12] * np.asarray(p[13]))
                       for p, s in pts)
        expected.append((key, tuple(weights @ positions), tuple(normal / norm), total,
                         tuple(friction)))
    got = [((c.body_a, c.link_a, c.body_b, c.link_b), c.position, c.normal, c.normal_force,
            c.friction) for c in physics.contacts()]
    assert len(got) == len(expected) >= 5
    assert got == expected


def test_a_shape_of_an_assets_lists_is_a_hashable_shape_of_floats():
    """A gripper asset gives sizes as YAML lists; its shapes must still be hashable (the
    monitor keeps its markers' template per layout) and equal to the same tuples."""
    from projection_server.simulation.physics import Shape

    from_asset = Shape('box', [0.02, 0.01, 1], [0.3, 0.3, 0.35, 1], [0, 0, 0, 1])
    assert from_asset == Shape('box', (0.02, 0.01, 1.0), (0.3, 0.3, 0.35, 1.0))
    assert hash(from_asset) == hash(Shape('box', (0.02, 0.01, 1.0), (0.3, 0.3, 0.35, 1.0)))
    assert all(type(x) is float for x in (*from_asset.size, *from_asset.orientation))
