"""Outcomes for any object: drops as free falls, tipping over, displacements and final
poses, read off constructed monitoring samples and off projections; and bags that recorded
older timeline settings."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from projection_server.settings import load_settings, TimelineSettings
from projection_server.timeline.rules import Rules
from projection_server.timeline.samples import Gripper, Poses, Sample

RATE, PER_SAMPLE = 240, 4   # physics steps per second, and per monitoring sample (60 Hz)
G = 9.81
EYE = np.eye(3)


def sample(t, poses, contacts=(), moving=('box',), **fields):
    """A monitoring sample at ``t`` [s] of ``poses`` (name -> position or (position,
    rotation)) and ``contacts`` (body_a, link_a, body_b, link_b, force)."""
    frames = Poses()
    for name, pose in poses.items():
        if not isinstance(pose, tuple):
            pose = (np.asarray(pose, dtype=float), EYE)
        frames.setdefault(name, pose)
    return Sample(t, poses=frames, moving=set(moving),
                  contacts=[(*c, 1.0) for c in contacts], **fields)


def events(samples, name=None):
    rules = Rules(samples, load_settings().timeline)
    return [e for e in rules.events() if name is None or e[0] == name]


# --- drop: a free fall of drop_min_fall or more -------------------------------------------

def falling_box(fall, release, duration=1.0):
    """A box resting on a ledge at 1 m that leaves it at ``release`` [s] and falls ``fall``
    [m] onto the floor below, as the monitor logs it: a sample has a contact if the box
    touched something in any physics step since the previous sample."""
    land = release + math.sqrt(2 * fall / G)

    def height(t):
        if t <= release:
            return 1.0
        return 1.0 - fall if t >= land else 1.0 - G * (t - release) ** 2 / 2

    samples = []
    for k in range(int(duration * RATE / PER_SAMPLE) + 1):
        steps = [(k * PER_SAMPLE - j) / RATE for j in range(PER_SAMPLE) if k * PER_SAMPLE - j > 0]
        touched = any(t <= release or t >= land for t in steps) or k == 0
        contacts = [('box', '', 'ledge', '', 2.0)] if touched else []
        samples.append(sample(k * PER_SAMPLE / RATE, {'box': [0.0, 0.0, height(k / 60)]},
                              contacts))
    return samples, land


# Release times at every phase of the sampling period (a sample every 1/60 s).
PHASES = [0.5 + i / 240 + 0.3 / 240 * j for i in range(4) for j in range(3)]


@pytest.mark.parametrize('release', PHASES)
@pytest.mark.parametrize('fall', [0.01, 0.02])
def test_a_fall_of_a_centimetre_or_two_is_a_drop_at_any_phase_of_the_samples(fall, release):
    samples, land = falling_box(fall, release)
    (drop,) = events(samples, 'drop')
    assert drop[1] == ['box'] and release < drop[2] <= drop[3] < land


@pytest.mark.parametrize('release', PHASES[::3])
def test_a_fall_of_half_a_centimetre_is_no_drop(release):
    assert events(falling_box(0.005, release)[0], 'drop') == []


def test_a_long_fall_spans_the_samples_without_contact():
    samples, land = falling_box(0.3, 0.5)
    (drop,) = events(samples, 'drop')
    assert drop[2] == pytest.approx(0.5 + 1 / 60) and land - 1 / 60 < drop[3] < land


def test_a_box_resting_with_a_weak_contact_now_and_then_does_not_drop():
    samples = [sample(k / 60, {'box': [0.0, 0.0, 1.0 + 1e-4 * math.sin(k)]},
                      [('box', '', 'table', '', 0.005 if k % 7 == 3 else 2.0)])
               for k in range(120)]
    assert events(samples, 'drop') == []


def test_a_box_sliding_down_a_slope_does_not_drop():
    # 10 cm down in a second, on a slope it touches in every sample but a few.
    samples = [sample(k / 60, {'box': [0.2 * k / 60, 0.0, 1.0 - 0.1 * k / 60]},
                      [] if k % 20 == 10 else [('box', '', 'slope', '', 1.0)])
               for k in range(61)]
    assert events(samples, 'drop') == []


def test_a_box_lowered_in_a_gripper_does_not_drop():
    gripper = {'g': Gripper('close', ['l', 'r'])}
    samples = [sample(k / 60, {'box': [0.0, 0.0, 1.0 - 0.2 * min(k / 30, 1.0)]},
                      [('box', '', 'g', 'l', 3.0), ('box', '', 'g', 'r', 3.0)],
                      grippers=gripper)
               for k in range(61)]
    assert events(samples, 'drop') == []


# --- tipped_over: the up axis more than tip_angle from its start --------------------------

def rotation_x(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def turning_box(angles):
    return [sample(k / 60, {'box': (np.zeros(3), rotation_x(a))}) for k, a in enumerate(angles)]


def test_a_box_turned_past_45_degrees_tips_over_at_the_first_sample_past_them():
    angles = [math.radians(k) for k in range(0, 91)]
    (tip,) = events(turning_box(angles), 'tipped_over')
    assert tip[1] == ['box'] and tip[2] == tip[3] == pytest.approx(46 / 60)


def test_a_box_that_rocks_by_30_degrees_does_not_tip_over():
    angles = [math.radians(30) * math.sin(k / 10) for k in range(200)]
    assert events(turning_box(angles), 'tipped_over') == []


def test_a_box_tips_over_once_even_if_it_is_righted_and_tipped_again():
    angles = [math.radians(90) * abs(math.sin(k / 20)) for k in range(200)]
    assert len(events(turning_box(angles), 'tipped_over')) == 1


def test_the_up_axis_is_compared_with_the_first_samples_not_with_the_world():
    start = rotation_x(math.radians(80))   # lying on its side from the start
    samples = [sample(k / 60, {'box': (np.zeros(3), start @ rotation_x(math.radians(k)))})
               for k in range(40)]
    assert events(samples, 'tipped_over') == []


# --- displacement(O) and final_pose(O) ----------------------------------------------------

def test_every_body_has_its_displacement_and_final_pose():
    turned = (0.0, 0.0, math.sin(0.3), math.cos(0.3))   # 0.6 rad about z
    samples = []
    for k in range(31):
        poses = Poses()
        s = k / 30
        poses.add([('world', 'box', (0.3 * s, 0.4 * s, 1.0),
                    turned if k == 30 else (0.0, 0.0, 0.0, 1.0))])
        samples.append(Sample(k / 60, poses=poses, moving={'box'}))
    rules = Rules(samples, load_settings().timeline)
    quantities = {(q[0], tuple(q[1])): q[2] for q in rules.quantities()}
    assert quantities[('displacement', ('box',))] == pytest.approx(0.5)
    position, quaternion = quantities[('final_pose', ('box',))]
    assert position == pytest.approx([0.3, 0.4, 1.0]) and quaternion == list(turned)
    assert json.loads(json.dumps(quantities[('final_pose', ('box',))])) == [position,
                                                                            quaternion]


def test_a_final_pose_of_a_composed_frame_is_a_unit_quaternion_of_its_rotation():
    poses = Poses()
    poses.setdefault('box', (np.zeros(3), rotation_x(2.5)))
    x, y, z, w = poses.quaternion('box')
    assert (x, y, z) == pytest.approx((math.sin(1.25), 0.0, 0.0)) and w == pytest.approx(
        math.cos(1.25))


# --- settings -------------------------------------------------------------------------------

def test_a_bag_with_the_old_drop_setting_is_read_with_the_files_new_ones():
    current = load_settings().timeline
    old = {'gap_merge': 0.2, 'contact_force_min': 0.01, 'support_max_angle': 0.7854,
           'slip_distance': 0.005, 'slip_angle': 0.2, 'grasp_settle': 0.2,
           'drop_min_duration': 0.05}
    settings = TimelineSettings.recorded(old)
    assert settings.gap_merge == 0.2   # what the bag recorded
    assert (settings.drop_min_fall, settings.tip_angle) == (current.drop_min_fall,
                                                            current.tip_angle)
    assert TimelineSettings.recorded(dataclasses.asdict(current)) == current


def test_every_timeline_setting_is_physical_and_documented_with_its_unit():
    from projection_server.settings import config_path

    text = config_path().read_text()
    for name in TimelineSettings.__dataclass_fields__:
        (line,) = [line for line in text.splitlines() if line.strip().startswith(name + ':')]
        unit = line.split('#', 1)[1].split(';')[0].split()[0]
        assert unit in ('s', 'N', 'm', 'rad'), line


# --- in projections -------------------------------------------------------------------------

def project(scenario, tmp_path, **params):
    from projection_server.simulation import Job
    from projection_server.workers.run import run_projection, translate_bag

    timeline = run_projection(Job.checked(scenario, 'grasp_object', params), load_settings(),
                              tmp_path / 'grasp')
    assert translate_bag(tmp_path / 'grasp') == timeline
    return timeline


@pytest.mark.parametrize('breaking_force', [10.0, 3.0])
def test_an_egg_that_slips_out_of_a_weak_grip_drops_and_what_it_lands_in_holds_after(
        make_scenario, tmp_path, breaking_force):
    # Section II's question: what holds for the egg after it was dropped?
    scenario = make_scenario(mass=0.1, friction=0.35, breaking_force=breaking_force)
    scenario['entities'][1]['parts'] = [{'name': 'pr2_gripper', 'class': 'gripper',
                                         'properties': {'urdf': 'pr2_gripper.urdf',
                                                        'friction': 1.0, 'restitution': 0.0,
                                                        'max_force': 80.0,
                                                        'max_opening': 0.09}}]
    timeline = project(scenario, tmp_path, force=1.5)
    (drop,) = [e for e in timeline['events'] if e[0] == 'drop']
    assert drop[1] == ['egg1']
    after = {f[0] for f in timeline['fluents'] if f[1][0] == 'egg1' and f[2] > drop[3]}
    assert 'on' in after and ('broken' in after) == (breaking_force < 5.0)
