"""Outcomes for any object: drops as free falls, read off constructed monitoring samples and
off projections; and bags that recorded older timeline settings."""

from __future__ import annotations

import dataclasses
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


# --- settings -------------------------------------------------------------------------------

def test_a_bag_with_the_old_drop_setting_is_read_with_the_files_new_ones():
    current = load_settings().timeline
    old = {'gap_merge': 0.2, 'contact_force_min': 0.01, 'support_max_angle': 0.7854,
           'slip_distance': 0.005, 'slip_angle': 0.2, 'grasp_settle': 0.2,
           'drop_min_duration': 0.05}
    settings = TimelineSettings.recorded(old)
    assert settings.gap_merge == 0.2   # what the bag recorded
    assert settings.drop_min_fall == current.drop_min_fall
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
