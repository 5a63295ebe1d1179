"""pour: the measures of Table II (Kunze et al. 2011) emerge from the particles' physics."""

from __future__ import annotations

import contextlib
import copy
from dataclasses import astuple
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from projection_server.simulation import Job, ProjectionError
from projection_server.simulation.programs import get as get_program
from projection_server.simulation.programs.pour import POUR_SIDE
from projection_server.simulation.scenario import parse_scenario
from projection_server.timeline import pouring
from projection_server.workers.run import translate_bag

POURING = yaml.safe_load((Path(__file__).parent / 'pouring.yaml').read_text())
COUNT = 300


# --- the pure measures -----------------------------------------------------------------
def test_particles_on_a_disc_are_over_it_and_close_above_its_top():
    disc = pouring.Disc((0.1, 0.0), 0.75, 0.15)
    positions = np.array([[0.1, 0.0, 0.755], [0.25, 0.0, 0.755], [0.3, 0.0, 0.755],
                          [0.1, 0.0, 0.9], [0.1, 0.0, 0.73]])
    assert pouring.on_disc(positions, disc, 0.005).tolist() == [True, True, False, False,
                                                                False]


def test_particles_in_a_tilted_vessel_are_found_in_its_frame():
    rotation = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])   # 90 deg about y
    vessel = pouring.Vessel((0.0, 0.0, 1.0), rotation, 0.04, -0.05, 0.05)
    positions = np.array([[0.04, 0.0, 1.0], [0.0, 0.0, 1.06], [0.07, 0.0, 1.0],
                          [0.0, 0.0, 1.0]])   # along the axis, beside it, past the rim, centre
    assert pouring.in_vessel(positions, vessel, 0.005).tolist() == [True, False, False, True]


def test_centroid_offset_is_relative_and_undefined_without_particles():
    xy = np.array([[0.1, 0.2], [0.3, 0.2]])
    assert pouring.centroid_offset(xy, (0.1, 0.1)) == pytest.approx((0.1, 0.1))
    assert pouring.centroid_offset(np.zeros((0, 2)), (0.0, 0.0)) is None


def test_spread_area_is_a_discs_area_for_points_spread_uniformly_over_it():
    rng = np.random.default_rng(0)
    r, angle = 0.05 * np.sqrt(rng.random(20000)), 2 * math.pi * rng.random(20000)
    xy = np.c_[r * np.cos(angle), r * np.sin(angle)]
    assert pouring.spread_area(xy) == pytest.approx(math.pi * 0.05 ** 2, rel=0.02)
    assert pouring.spread_area(2 * xy) == pytest.approx(4 * pouring.spread_area(xy))
    assert pouring.spread_area(xy[:1]) is None


def test_roundness_is_one_for_a_circle_zero_for_a_line_undefined_below_two():
    angles = np.linspace(0, 2 * math.pi, 36, endpoint=False)
    assert pouring.roundness(np.c_[np.cos(angles), np.sin(angles)]) == pytest.approx(1.0)
    assert pouring.roundness(np.c_[2 * np.cos(angles), np.sin(angles)]) == pytest.approx(0.25)
    assert pouring.roundness(np.array([[0.0, 0.0], [1.0, 1.0]])) == pytest.approx(0.0)
    assert pouring.roundness(np.array([[0.0, 0.0]])) is None


# --- scenario and parameters -----------------------------------------------------------
def test_the_knowledge_base_keys_are_read_and_older_keys_still_accepted():
    scenario = parse_scenario(POURING)
    cup, mix = scenario.entities[3], scenario.entities[4]
    assert cup.properties['radius'] == 0.045 and cup.properties['wall_thickness'] == 0.004
    assert mix.properties['particle_count'] == COUNT and mix.properties['container'] == 'cup1'
    old = copy.deepcopy(POURING)
    old['entities'][1]['properties'] = {'diameter': 0.09, 'height': 0.11, 'mass': 0.2}
    assert parse_scenario(old).entities[3].properties['radius'] == pytest.approx(0.045)
    del old['entities'][2]['properties']['radius']   # the maker's, without a diameter
    with pytest.raises(ProjectionError, match='radius'):
        parse_scenario(old)


def test_pour_declares_its_parameters_with_units_and_ranges():
    params = {p['name']: p for p in get_program('pour').describe()['params']}
    assert [params[n]['unit'] for n in ('angle', 'time', 'position')] == ['rad', 's', 'm']
    assert params['angle']['min'] <= 1.84 and params['angle']['max'] >= 2.14
    assert params['position']['min'] <= -0.09 and params['position']['max'] >= 0.07
    with pytest.raises(ProjectionError):
        Job.checked(POURING, 'pour', {'angle': 4.0})


def test_the_cups_wall_is_closed_all_round():
    # A particle of the batter, put against the inside of the wall at every 5 degrees and
    # at three heights, touches the wall there (PyBullet keeps 16 shapes of a compound:
    # with a 17th the cup had a slot 20 degrees wide that batter ran out of).
    import pybullet
    from pybullet_utils.bullet_client import BulletClient
    from projection_server.settings import load_settings
    from projection_server.simulation.world import build_world

    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        scenario = copy.deepcopy(POURING)
        scenario['entities'][1]['parts'][0]['properties']['particle_count'] = 1
        physics = build_world(client, parse_scenario(scenario), load_settings())
        cup = physics.body('cup1').body_id
        (cx, cy, cz), _ = client.getBasePositionAndOrientation(cup)
        probe = client.createMultiBody(0.0005, client.createCollisionShape(
            client.GEOM_SPHERE, radius=0.0048), -1, [0.0, 0.0, 2.0])
        inner = 0.045 - 0.004
        gaps = []
        for degrees in range(0, 360, 5):
            a = math.radians(degrees)
            for z in (-0.03, 0.0, 0.03):
                # the probe's centre on the wall's inside: the wall overlaps it by mm
                r = inner
                client.resetBasePositionAndOrientation(
                    probe, [cx + r * math.cos(a), cy + r * math.sin(a), cz + z], [0, 0, 0, 1])
                points = client.getClosestPoints(probe, cup, 0.005)
                if not points or min(q[8] for q in points) > -0.002:
                    gaps.append((degrees, z))
        assert gaps == []
    finally:
        client.disconnect()


def test_a_compound_of_more_shapes_than_pybullet_keeps_is_refused():
    import pybullet
    from pybullet_utils.bullet_client import BulletClient
    from projection_server.simulation.objects.common import compound_shape, MAX_COMPOUND_SHAPES

    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        n = MAX_COMPOUND_SHAPES
        shape = compound_shape(client, [client.GEOM_SPHERE] * n, radii=[0.01] * n,
                               collisionFramePositions=[[0.03 * i, 0, 0] for i in range(n)])
        body = client.createMultiBody(1.0, shape, -1, [0, 0, 1])
        assert len(client.getCollisionShapeData(body, -1)) == n
        with pytest.raises(ProjectionError, match='PyBullet keeps only 16'):
            compound_shape(client, [client.GEOM_SPHERE] * (n + 1), radii=[0.01] * (n + 1),
                           collisionFramePositions=[[0.03 * i, 0, 0] for i in range(n + 1)])
    finally:
        client.disconnect()


# --- projections -----------------------------------------------------------------------
# The (angle, time, position) points the tests below pour at.
POINTS = [(2.14, 0.0, 0.0), (1.84, 0.0, 0.0), (1.84, 1.0, 0.0), (2.14, 1.0, 0.0),
          (2.14, 1.0, -0.09), (2.14, 1.0, 0.07)]


@pytest.fixture(scope='module')
def pour(pool):
    """``pour(angle, time, position)`` -> timeline (each point projected once). The
    :data:`POINTS` are queued together when the first is asked for, as a query's
    parametrizations are: the pours from one position run as one tree, stepping what they
    share once (each bag the one it would be alone: test_branching)."""
    futures, cache = {}, {}

    def job(angle, time, position):
        return Job.checked(POURING, 'pour', {'angle': angle, 'time': time,
                                             'position': position})

    def run(angle, time, position):
        key = (angle, time, position)
        if not futures:
            # The simulation's wall-clock limit, a loaded machine's (not what is tested).
            futures.update(zip(POINTS, pool.submit_all([job(*p) for p in POINTS], 600.0)))
        if key not in cache:
            if key not in futures:
                futures[key] = pool.submit(job(*key), 600.0)
            cache[key] = translate_bag(futures[key].result(timeout=1200.0).bag)
        return cache[key]
    return run


def measure(timeline, name, arg):
    values = [q[2] for q in timeline['quantities'] if q[0] == name and q[1] == [arg]]
    return values[0] if values else None


def on_maker(timeline):
    return measure(timeline, 'particles_on', 'pancake_maker1')


def spilled(timeline):
    return measure(timeline, 'particles_spilled', 'pancake_mix1')


def in_cup(timeline):
    return measure(timeline, 'particles_in', 'cup1')


def test_every_particle_is_counted_once_and_the_timeline_has_the_measures(pour):
    timeline = pour(2.14, 0.0, 0.0)
    assert on_maker(timeline) + spilled(timeline) + in_cup(timeline) == COUNT
    assert 0.0 <= measure(timeline, 'roundness', 'pancake_maker1') <= 1.0
    assert abs(measure(timeline, 'centroid_offset_x', 'pancake_maker1')) < 0.15
    assert ['on', ['pancake_mix1', 'pancake_maker1']] in [f[:2] for f in timeline['fluents']]
    spills = [e for e in timeline['events'] if e[0] == 'spill']
    assert (spills != []) == (spilled(timeline) > 0)
    assert all(e[1] == ['pancake_mix1'] and e[2] > 0.3 for e in spills)   # not before tilting


def test_the_batter_lands_just_beyond_the_lip_on_the_side_the_cup_pours_to(pour):
    # The lip is over the maker's centre and the cup pours to POUR_SIDE (the paper's -x).
    off = measure(pour(2.14, 0.0, 0.0), 'centroid_offset_x', 'pancake_maker1')
    assert 0.0 < POUR_SIDE * off < 0.04


def test_a_larger_angle_puts_more_mix_on_the_maker(pour):
    assert on_maker(pour(2.14, 0.0, 0.0)) > on_maker(pour(1.84, 0.0, 0.0))


def test_a_cup_tilted_little_past_horizontal_keeps_part_of_its_content_at_a_short_hold(pour):
    assert in_cup(pour(1.84, 0.0, 0.0)) > COUNT // 5


def test_a_longer_hold_at_the_same_angle_puts_more_on_the_maker(pour):
    assert on_maker(pour(1.84, 1.0, 0.0)) > on_maker(pour(1.84, 0.0, 0.0))
    assert in_cup(pour(1.84, 1.0, 0.0)) < in_cup(pour(1.84, 0.0, 0.0))


def test_the_centroid_follows_the_cups_offset(pour):
    left, right = pour(2.14, 1.0, -0.09), pour(2.14, 1.0, 0.07)
    assert measure(left, 'centroid_offset_y', 'pancake_maker1') < -0.05
    assert measure(right, 'centroid_offset_y', 'pancake_maker1') > 0.04
    assert abs(measure(pour(2.14, 1.0, 0.0), 'centroid_offset_y', 'pancake_maker1')) < 0.02


def test_a_centred_pour_spills_little_and_less_than_an_off_centre_one(pour):
    # The pan's edge is 15 cm from its centre, 6 cm from the -0.09 offset and 8 cm from 0.07.
    centre = spilled(pour(2.14, 1.0, 0.0))
    assert centre <= COUNT // 20
    assert spilled(pour(2.14, 1.0, -0.09)) > centre
    assert spilled(pour(2.14, 1.0, 0.07)) >= centre


def test_the_positions_of_the_particles_on_the_maker_are_in_the_timeline(pour):
    # World [x, y, z] of each particle on the maker: what the object factory builds a
    # pancake from (object_model(pancake, _{particles: Points}, E)).
    timeline = pour(2.14, 1.0, 0.0)
    points = np.asarray(measure(timeline, 'particles_on_positions', 'pancake_maker1'))
    assert points.shape == (on_maker(timeline), 3)
    maker = POURING['entities'][2]
    (x, y, z), p = maker['pose']['xyz'], maker['properties']
    assert np.all(np.hypot(points[:, 0] - x, points[:, 1] - y) <= p['radius'] + 0.0048)
    assert np.all(points[:, 2] >= z + p['height'] / 2)
    offset = points[:, :2].mean(axis=0) - (x, y)
    assert offset.tolist() == pytest.approx(
        [measure(timeline, 'centroid_offset_x', 'pancake_maker1'),
         measure(timeline, 'centroid_offset_y', 'pancake_maker1')])


@contextlib.contextmanager
def _pour_world(scenario, params, physics=None):
    """``(physics, task)``: a pour of ``scenario`` (a description) with ``params``, its
    world in a PyBullet client of its own (``physics``: settings over the pour's)."""
    import pybullet
    from pybullet_utils.bullet_client import BulletClient
    from projection_server.settings import load_settings
    from projection_server.simulation.world import build_world

    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        world = parse_scenario(scenario)
        built = build_world(client, world, load_settings().for_projection('pour', physics))
        yield built, get_program('pour').create(built, world, params,
                                                np.random.default_rng(0))
    finally:
        client.disconnect()


def _cup_tilts(rate_hz, angle=1.99, hold=0.0, count=10):
    """(commanded, actual) tilt of the cup at every 60 Hz sample of a pour at ``rate_hz``,
    and the simulated seconds at which the pour said it had finished (None: never)."""
    scenario = copy.deepcopy(POURING)
    scenario['entities'][1]['parts'][0]['properties']['particle_count'] = count
    with _pour_world(scenario, {'angle': angle, 'time': hold, 'position': 0.0},
                     {'rate_hz': rate_hz}) as (physics, task):
        client, settings = physics.client, physics.settings
        cup = physics.body('cup1').body_id
        control, log = settings.control.steps_per_control, settings.control.steps_per_log
        tilts, finished = [], None
        for step in range(math.ceil(task.duration * rate_hz)):
            if step % control == 0:
                task.control(physics)
            physics.step()
            if physics.step_count % log == 0:
                rotation = client.getMatrixFromQuaternion(
                    client.getBasePositionAndOrientation(cup)[1])
                # tilt about y from the cup's z axis (x and z components of its third column)
                tilts.append((task.tilt(physics.time),
                              math.atan2(POUR_SIDE * rotation[2], rotation[8])))
                if finished is None and task.finished(physics):
                    finished = physics.time
    return np.array(tilts), finished


def test_the_cup_moves_along_its_commanded_path_at_every_time_step():
    # The cup is what moves the batter: if its path depended on the step, so would the pour
    # (a target changed only at control steps made it jerk, the more the finer the step).
    coarse, _ = _cup_tilts(240)
    fine, _ = _cup_tilts(960)
    assert coarse[:, 0].max() > 1.95
    for tilts in (coarse, fine):
        off = np.abs(tilts[:, 1] - tilts[:, 0])
        assert np.percentile(off, 90) < 1e-3   # on the path, not trailing it
        assert off.max() < 0.025               # a few steps of the turn at the top
    n = min(len(coarse), len(fine))   # the last sample may fall on either side of the end
    assert np.abs(coarse[:n, 1] - fine[:n, 1]).max() < 0.02


def test_a_pour_ends_once_the_poured_batter_is_at_rest_and_not_before_the_cup_is_upright():
    from projection_server.simulation.programs.pour import AFTER, SETTLE, tilt_duration
    tilts, finished = _cup_tilts(240, angle=2.14, count=30)
    upright = SETTLE + 2 * tilt_duration(2.14)   # settling, tilting and tilting back
    assert finished is not None and upright <= finished < upright + AFTER
    assert tilts[-1, 1] == pytest.approx(0.0, abs=1e-3)


def test_the_measures_of_a_pour_converge_at_a_2x_finer_step(pool):
    # The pour runs with settings of its own (config/physics.yaml, programs.pour); a 2x
    # finer time step with 2x the solver iterations must give the same measures within the
    # reference tolerances of bench/fidelity.py (which checks the whole of Table II at 4x).
    # The whole batch, held 1 s at the largest angle (Table II's pour that puts the most on
    # the pan): the roundness of the small patch that a third of the batch leaves scatters
    # with the step (0.52, 0.65, 0.57 at 1x, 2x, 4x; bench/RESULTS.md, 2026-11-29).
    # At the centre: 0.09 m off it, by the pan's edge, what runs over the edge is not
    # converged (spill 6 at 240 Hz against 2 at 480 Hz; bench/RESULTS.md, 2026-11-28).
    from projection_server.reproduce.fidelity import REFERENCE_TOLERANCES
    scenario = copy.deepcopy(POURING)
    own = pool.settings.for_projection('pour').physics
    finer = {'rate_hz': 2 * own.rate_hz, 'solver_iterations': 2 * own.solver_iterations}
    measures = []
    for physics in ({}, finer):
        job = Job.checked(scenario, 'pour', {'angle': 2.14, 'time': 1.0, 'position': 0.0},
                          physics)
        timeline = translate_bag(pool.run(job, timeout=300.0))
        measures.append({'pan': on_maker(timeline), 'spill': spilled(timeline),
                         'round': measure(timeline, 'roundness', 'pancake_maker1')})
    ours, reference = measures
    assert reference['pan'] > COUNT // 10
    for column, value in reference.items():
        assert abs(ours[column] - value) <= REFERENCE_TOLERANCES[column](value), measures


def test_the_contacts_of_a_pour_are_those_of_all_points_without_particle_pairs():
    # Physics.contacts asks Bullet body by body so as not to build the thousands of
    # particle-particle points of each sample; the samples must be the same.
    with _pour_world(POURING, {'angle': 2.14, 'time': 0.0, 'position': -0.09}) as (
            physics, task):
        settings = physics.settings
        for step in range(int(2.6 * settings.physics.rate_hz)):   # the stream has landed
            if step % settings.control.steps_per_control == 0:
                task.control(physics)
            physics.step()
        fast = physics.contacts()
        physics._contact_points = physics.client.getContactPoints
        every = physics.contacts()
    assert [c[:4] for c in map(astuple, fast)] == [c[:4] for c in map(astuple, every)]
    assert {c.body_a for c in fast} >= {'cup1', 'pancake_maker1'}
    assert any(c.body_a == c.body_b == 'pancake_mix1' for c in every) is False
    for a, b in zip(fast, every):
        assert a.normal_force == pytest.approx(b.normal_force, rel=1e-9, abs=1e-12)
        assert a.position == pytest.approx(b.position, abs=1e-9)
        assert a.normal == pytest.approx(b.normal, abs=1e-9)
        assert a.friction == pytest.approx(b.friction, abs=1e-9)


def test_principal_axes_of_a_line_point_along_it():
    t = np.linspace(-1.0, 1.0, 21)
    centroid, eigenvalues, vectors = pouring.principal_axes(np.c_[t + 2.0, t])
    assert centroid.tolist() == pytest.approx([2.0, 0.0])
    assert eigenvalues[0] == pytest.approx(0.0, abs=1e-12) and eigenvalues[1] > 0
    assert abs(vectors[:, 1] @ np.array([1.0, 1.0]) / math.sqrt(2)) == pytest.approx(1.0)
    assert pouring.principal_axes(np.zeros((1, 2))) is None


def test_the_figure_6_plot_is_drawn_from_a_pours_bag(pour, tmp_path):
    from projection_server.reproduce.experiments import Run, TABLE_II_POURING
    from projection_server.reproduce.report import pca_png
    timeline = pour(2.14, 1.0, 0.0)
    value = {'pan': on_maker(timeline),
             'off_x': measure(timeline, 'centroid_offset_x', 'pancake_maker1'),
             'off_y': measure(timeline, 'centroid_offset_y', 'pancake_maker1'),
             'round': measure(timeline, 'roundness', 'pancake_maker1')}
    run = Run((0.0, 1.0, 2.14), value, timeline['meta']['bag'], 4.0, [], 1.0)
    png = pca_png(TABLE_II_POURING, [run], tmp_path / 'pca.png')
    assert png.read_bytes().startswith(b'\x89PNG\r\n\x1a\n') and png.stat().st_size > 5000


def test_the_particles_velocities_are_their_positions_change_over_a_step():
    """Physics.particle_state gives a fluid's velocities as its particles' positions' change
    over the last step (not read from Bullet) whenever it read them a step before; they must
    be Bullet's own velocities, through a cohesive, viscous pour from a moving cup."""
    scenario = copy.deepcopy(POURING)
    scenario['entities'][1]['parts'][0]['properties'].update(
        particle_count=120, rolling_friction=0.0, spinning_friction=0.0,
        rotational_inertia=10000.0, surface_tension=0.15, viscosity=60.0)
    with _pour_world(scenario, {'angle': 2.14, 'time': 0.0, 'position': 0.0}) as (
            physics, task):
        client, settings = physics.client, physics.settings
        ids = physics.fluids['pancake_mix1'].body_ids
        control, worst, fastest, derived = settings.control.steps_per_control, 0.0, 0.0, 0
        for step in range(round(4.0 * settings.physics.rate_hz)):
            if step % control == 0:
                task.control(physics)
            physics.step()   # the batter's hook reads the state each step
            _, v = physics.particle_state('pancake_mix1', velocities=True)
            derived += physics._fluid_states['pancake_mix1'].before is not None
            bullet = np.array([client.getBaseVelocity(i)[0] for i in ids])
            worst = max(worst, float(np.abs(v - bullet).max()))
            fastest = max(fastest, float(np.abs(bullet).max()))
    assert fastest > 0.15           # the batter flowed out of the cup
    assert derived == step          # every step but the first
    assert worst < 1e-9, worst
