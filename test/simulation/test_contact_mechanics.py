"""The egg shell's contact-pressure model (equivalent loads)."""

from __future__ import annotations

import math

import numpy as np
import pybullet
from pybullet_utils.bullet_client import BulletClient
import pytest

from projection_server.simulation import contact_mechanics as cm, load_settings
from projection_server.simulation.programs import get as get_program
from projection_server.simulation.scenario import parse_scenario
from projection_server.simulation.world import build_world

EGG = (0.029, 0.022, 0.022)     # semi-axes [m]
K = 1.0e9                       # pad foundation modulus [N/m^3]
RIM = 0.005                     # pad rim radius [m]
ROT, POS = np.eye(3), np.zeros(3)
AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])   # pad face: along the egg, and up
NORMAL = np.array([0.0, -1.0, 0.0])                  # from the pad (at +y) to the egg


def load_of_pad(force, offset, half_length=0.022):
    """Equivalent load of a pad at +y whose centre is ``offset`` along the egg's axis."""
    centre = np.array([offset, EGG[1], 0.0])
    peak = cm.pad_peak_pressure(force, EGG, ROT, POS, centre, AXES, NORMAL,
                                (half_length, 0.01), K, RIM)
    return cm.equivalent_load(peak, K, EGG)


def test_a_centred_pad_loads_the_egg_with_the_grip_force():
    for force in (1.0, 5.0, 11.0):
        assert load_of_pad(force, 0.0) == pytest.approx(force, rel=1e-6)


def test_the_numerical_solution_matches_the_closed_form_on_a_large_face():
    centre = np.array([0.0, EGG[1], 0.0])
    closed = math.sqrt(K * 10.0 / (math.pi * EGG[0]))
    large = cm.pad_peak_pressure(10.0, EGG, ROT, POS, centre, AXES, NORMAL, (0.05, 0.05), K,
                                 RIM)
    small = cm.pad_peak_pressure(10.0, EGG, ROT, POS, centre, AXES, NORMAL, (0.0035, 0.0035),
                                 K, RIM)
    assert large == pytest.approx(closed, rel=0.01)
    assert small > closed   # the small face cuts the patch: the pressure rises


def test_a_pad_edge_near_the_equator_concentrates_the_load():
    assert load_of_pad(9.0, 0.02) > 1.1 * 9.0
    assert load_of_pad(9.0, 0.02) > load_of_pad(9.0, 0.015) > 0.98 * 9.0


def test_the_edge_effect_grows_with_the_force():
    ratios = [load_of_pad(f, 0.02) / f for f in (1.0, 5.0, 11.0)]
    assert ratios == sorted(ratios)


def test_a_shell_on_the_rim_is_loaded_by_the_rims_curvature():
    # The pad's lower rim rides on the egg's upper half (as when the egg slips down).
    centre = np.array([0.0, EGG[1], 0.016])
    load = cm.equivalent_load(cm.pad_peak_pressure(3.0, EGG, ROT, POS, centre, AXES, NORMAL,
                                                   (0.022, 0.01), K, RIM), K, EGG)
    assert 1.5 * 3.0 < load < 4.0 * 3.0
    sharper = cm.pad_peak_pressure(3.0, EGG, ROT, POS, centre, AXES, NORMAL, (0.022, 0.01),
                                   K, RIM / 5)
    assert cm.equivalent_load(sharper, K, EGG) > load


def test_a_pad_beside_the_shell_carries_nothing():
    centre = np.array([0.2, EGG[1], 0.0])
    assert cm.pad_peak_pressure(5.0, EGG, ROT, POS, centre, AXES, NORMAL, (0.01, 0.01),
                                K, RIM) is None


def test_the_pointed_end_is_weaker_than_the_side_on_a_flat_surface():
    side = cm.curvature_load(1.0, EGG, np.array([0.0, 0.0, EGG[2]]))
    end = cm.curvature_load(1.0, EGG, np.array([EGG[0], 0.0, 0.0]))
    assert side == pytest.approx(1.0)
    assert end == pytest.approx(EGG[0] ** 2 / EGG[1] ** 2)


def test_indentation_balances_the_force_exactly():
    gaps = np.array([0.0, 1e-4, 2e-4, 5e-4])
    delta, active = cm.winkler_indentation(gaps, 1e-6, 0.1, 1e9)
    assert 1e9 * 1e-6 * np.clip(delta - gaps, 0, None).sum() == pytest.approx(0.1)
    assert active == int((gaps < delta).sum())


def shell_loads(client, scenario, settings, seconds, cache=True, program=None):
    """Per-step loads of egg1's shell model over ``seconds`` of a world (and program)."""
    physics = build_world(client, parse_scenario(scenario), settings)
    task = None
    if program is not None:
        task = get_program(program[0]).create(physics, parse_scenario(scenario), program[1],
                                              np.random.default_rng(0))
    (shell,) = physics.models
    shell.cache = cache
    loads, peaks = [], []
    for step in range(round(seconds * settings.physics.rate_hz)):
        if task is not None and step % settings.control.steps_per_control == 0:
            task.control(physics)
        physics.step()
        loads.append(shell.load)
        peaks.append(shell._window[-1] if shell._window else 0.0)
    return np.array(loads), np.array(peaks)


@pytest.fixture
def client():
    bullet = BulletClient(connection_mode=pybullet.DIRECT)
    yield bullet
    bullet.disconnect()


def test_the_load_of_a_drop_converges_as_the_time_step_shrinks(client, make_scenario,
                                                               refined_settings):
    scenario = make_scenario(breaking_force=None)
    scenario['entities'][-1]['pose']['xyz'][2] += 0.05   # 5 cm above the table
    coarse, coarse_peaks = shell_loads(client, scenario, refined_settings(1), 0.4)
    fine, fine_peaks = shell_loads(client, scenario, refined_settings(4), 0.4)
    # A single step's force grows as the step shrinks; the window's average does not.
    assert fine_peaks.max() > 2.5 * coarse_peaks.max()
    assert fine.max() == pytest.approx(coarse.max(), rel=0.1)
    assert 1.0 < coarse.max() < 10.0


def test_cached_pad_solutions_are_within_the_models_own_tolerance(client, make_scenario):
    # The pad model's own discretisation error (40 x 40 grid against a 4 times finer one)
    # at an off-centre grasp is a few per cent; re-using solutions adds well under that.
    grid = cm._GRID
    try:
        cm._GRID = 160
        fine_grid = load_of_pad(9.0, 0.02)
    finally:
        cm._GRID = grid
    tolerance = abs(load_of_pad(9.0, 0.02) / fine_grid - 1.0)
    assert 0.005 < tolerance < 0.05
    scenario = make_scenario(breaking_force=None)
    program = ('grasp_object', {'force': 9.0, 'position': 0.02, 'lift_time': 1.0})
    cached, _ = shell_loads(client, scenario, load_settings(), 3.0, True, program)
    solved, _ = shell_loads(client, scenario, load_settings(), 3.0, False, program)
    held = solved > 1.0
    assert held.sum() > 300
    assert np.abs(cached[held] / solved[held] - 1.0).max() < tolerance / 2


def test_the_written_out_arithmetic_is_the_loops_to_the_last_bit():
    """The per-step sums and quaternion products are written out for speed; written out,
    they must give the very floats of the loops they replace, or outcomes could move."""
    from projection_server.simulation import object_models as om

    def curvature_load_loop(force, a, point):
        scale = math.sqrt(sum((x / s) ** 2 for x, s in zip(point, a)))
        if scale == 0.0:
            return force
        radius = a[0] * a[1] * a[2] * sum((x / scale) ** 2 / s ** 4 for x, s in zip(point, a))
        return force * cm.reference_radius(a) / radius

    def rotate_loop(q, v):
        x, y, z, _ = om._multiply(om._multiply(q, (*v, 0.0)), om._conjugate(q))
        return (x, y, z)

    rng = np.random.default_rng(7)
    for _ in range(2000):
        a = tuple(float(x) for x in rng.uniform(0.01, 0.05, 3))
        point = tuple(float(x) for x in rng.normal(0.0, 0.03, 3))
        force = float(rng.uniform(0.0, 20.0))
        assert cm.curvature_load(force, a, point) == curvature_load_loop(force, a, point)
        q = rng.normal(size=4)
        q = tuple(float(x) for x in q / np.linalg.norm(q))
        r = rng.normal(size=4)
        r = tuple(float(x) for x in r / np.linalg.norm(r))
        assert om._rotate(q, point) == rotate_loop(q, point)
        assert om._angle(q, r) == 2.0 * math.acos(min(1.0, abs(sum(
            p * s for p, s in zip(q, r)))))


def test_the_pad_grids_arithmetic_is_numpys_plain_one_to_the_last_bit():
    """The pad's grid is built, solved and sorted with fewer array operations than the
    plain numpy way (linspace, meshgrid, masked roots, a full sort); each must give the very
    floats of the plain way, or loads, and with them outcomes, could move."""
    def gaps_masked(semi_axes, rot, pos, points, direction):
        inv = 1.0 / np.asarray(semi_axes)
        x0 = ((points - pos) @ rot) * inv
        d = (rot.T @ direction) * inv
        qa, qb = float(d @ d), 2.0 * (x0 @ d)
        disc = qb * qb - 4.0 * qa * (np.einsum('ij,ij->i', x0, x0) - 1.0)
        gaps = np.full(len(points), np.inf)
        hit = disc >= 0.0
        gaps[hit] = (-qb[hit] - np.sqrt(disc[hit])) / (2.0 * qa)
        return gaps

    def indentation_sorted(gaps, cell_area, force, stiffness):
        g = np.sort(gaps[np.isfinite(gaps)])
        delta = (force / (stiffness * cell_area) + np.cumsum(g)) / np.arange(1, g.size + 1)
        first = int(np.argmax(delta <= np.append(g[1:], np.inf)))
        return float(delta[first]), first + 1

    rng = np.random.default_rng(11)
    for _ in range(300):
        lo = rng.uniform(-0.02, 0.0, 2)
        hi = lo + rng.uniform(1e-4, 0.03, 2)
        grid = np.linspace(lo, hi, cm._GRID)
        for k in range(2):
            assert np.array_equal(grid[:, k], np.linspace(lo[k], hi[k], cm._GRID))
        u, v = grid.T
        centre = rng.normal(0.0, 0.05, 3)
        axes = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        uu, vv = np.meshgrid(u, v, indexing='ij')
        assert np.array_equal(cm._grid_points(centre, axes[:2], u, v),
                              centre + uu.reshape(-1, 1) * axes[0]
                              + vv.reshape(-1, 1) * axes[1])
        points = cm._grid_points(centre, axes[:2], u, v)
        semi_axes = tuple(rng.uniform(0.01, 0.04, 3))
        pos = centre + rng.normal(0.0, 0.01, 3) - 0.03 * axes[2]
        gaps = cm.ellipsoid_gaps(semi_axes, axes, pos, points, axes[2])
        assert np.array_equal(gaps, gaps_masked(semi_axes, axes, pos, points, axes[2]))
        if np.isfinite(gaps).any():
            force = float(rng.uniform(0.01, 50.0))
            cell = float(rng.uniform(1e-8, 1e-6))
            assert cm.winkler_indentation(gaps, cell, force, 1e9) == \
                indentation_sorted(gaps, cell, force, 1e9)
