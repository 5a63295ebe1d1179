"""grasp_object: outcomes emerge from physics and show up in the timeline."""

from __future__ import annotations

import numpy as np
import pytest

from projection_server.simulation import Job
from projection_server.workers.run import run_projection
from projection_server.workers.run import translate_bag


@pytest.fixture(scope='module')
def project(pool):
    """``project(scenario, force, position)`` -> timeline, through the worker pool."""
    def run(scenario, force, position=0.0):
        job = Job.checked(scenario, 'grasp_object', {'force': force, 'position': position})
        return translate_bag(pool.run(job, timeout=60.0))
    return run


def events(timeline, name, obj='egg1'):
    return [e for e in timeline['events'] if e[0] == name and e[1] == [obj]]


def quantity(timeline, name, obj='egg1'):
    (value,) = [q[2] for q in timeline['quantities'] if q[0] == name and q[1] == [obj]]
    return value


def test_a_weak_grip_lets_the_egg_slip(project, make_scenario):
    timeline = project(make_scenario(), force=1.0)
    assert events(timeline, 'grasp') and events(timeline, 'slip')
    assert not events(timeline, 'break') and not events(timeline, 'lift')
    assert quantity(timeline, 'lift_height') < 0.01


def test_a_moderate_grip_lifts_the_egg(project, make_scenario):
    timeline = project(make_scenario(), force=5.0)
    assert events(timeline, 'grasp') and events(timeline, 'lift')
    assert not events(timeline, 'slip') and not events(timeline, 'break')
    assert quantity(timeline, 'lift_height') == pytest.approx(0.1, abs=0.01)
    (held,) = [f for f in timeline['fluents'] if f[:2] == ['in_gripper', ['egg1']]]
    assert held[3] == timeline['meta']['duration']


def test_a_hard_grip_breaks_the_egg(project, make_scenario):
    timeline = project(make_scenario(), force=11.0)
    assert events(timeline, 'break')
    assert ['broken', ['egg1']] in [f[:2] for f in timeline['fluents']]
    assert quantity(timeline, 'max_load') >= quantity(timeline, 'load_limit') == 10.0


def test_a_stronger_shell_survives_the_same_grip(project, make_scenario):
    timeline = project(make_scenario(breaking_force=20.0), force=11.0)
    assert not events(timeline, 'break') and events(timeline, 'lift')


def test_an_off_centre_grip_breaks_the_egg_at_a_lower_force(project, make_scenario):
    assert not events(project(make_scenario(), force=9.0, position=0.0), 'break')
    assert events(project(make_scenario(), force=9.0, position=0.02), 'break')


def test_a_heavier_egg_needs_a_firmer_grip(project, make_scenario):
    assert not events(project(make_scenario(), force=3.0), 'slip')
    assert events(project(make_scenario(mass=0.15), force=3.0), 'slip')


def with_gripper(scenario, **properties):
    """The scenario with the robot's gripper described (KB values, changed by ``properties``)."""
    robot = scenario['entities'][1]
    robot['parts'] = [{'name': 'pr2_gripper', 'class': 'gripper', 'properties': {
        'urdf': 'pr2_gripper.urdf', 'friction': 1.0, 'restitution': 0.0,
        'max_force': 80.0, 'max_opening': 0.09, **properties}}]
    return scenario


def test_a_weak_grip_holds_the_egg_under_weaker_gravity(project, make_scenario):
    scenario = make_scenario()
    scenario['entities'][0]['properties']['gravity'] = 3.0
    assert events(project(make_scenario(), force=1.0), 'slip')
    held = project(scenario, force=1.0)
    assert not events(held, 'slip') and events(held, 'lift')


def test_the_grippers_max_force_caps_the_grip(project, make_scenario):
    assert events(project(with_gripper(make_scenario()), force=11.0), 'break')
    capped = project(with_gripper(make_scenario(), max_force=4.0), force=11.0)
    assert not events(capped, 'break') and events(capped, 'lift')
    assert quantity(capped, 'max_load') == pytest.approx(4.0, rel=0.05)


def test_fingers_that_cannot_open_wider_than_the_egg_do_not_grasp_it(project, make_scenario):
    assert events(project(with_gripper(make_scenario()), force=5.0), 'lift')
    narrow = project(with_gripper(make_scenario(), max_opening=0.03), force=5.0)
    # The fingers run into the egg instead of closing around it.
    assert not events(narrow, 'lift') and quantity(narrow, 'lift_height') < 0.01


def test_the_same_projection_gives_the_same_timeline_and_bag(make_scenario, tmp_path):
    job = Job.checked(make_scenario(), 'grasp_object', {'force': 7.0, 'position': 0.02})
    from projection_server.simulation import load_settings

    settings = load_settings()
    bags = [tmp_path / run / 'grasp' for run in ('a', 'b')]
    for bag in bags:
        bag.parent.mkdir()
        run_projection(job, settings, bag)
    first, second = (translate_bag(bag) for bag in bags)
    assert first['fluents'] == second['fluents'] and first['events'] == second['events']
    assert first['quantities'] == second['quantities']
    assert (bags[0] / 'grasp.mcap').read_bytes() == (bags[1] / 'grasp.mcap').read_bytes()


def outcome(timeline):
    return ('break' if events(timeline, 'break') else 'slip' if events(timeline, 'slip')
            else 'ok')


@pytest.mark.parametrize('force, position, expected', [
    (1.0, 0.0, 'slip'), (5.0, 0.02, 'ok'), (9.0, 0.02, 'break')])
def test_table_i_outcomes_do_not_depend_on_the_time_step(make_scenario, refined_settings,
                                                        tmp_path, force, position, expected):
    job = Job.checked(make_scenario(), 'grasp_object', {'force': force, 'position': position})
    outcomes, loads = [], []
    for factor in (1, 4):
        bag = tmp_path / f'x{factor}'
        run_projection(job, refined_settings(factor), bag)
        timeline = translate_bag(bag)
        outcomes.append(outcome(timeline))
        loads.append(quantity(timeline, 'max_load'))
    assert outcomes == [expected, expected]
    assert loads[1] == pytest.approx(loads[0], rel=0.15)


def test_the_timeline_has_the_contract_shape(project, make_scenario):
    timeline = project(make_scenario(), force=5.0)
    assert set(timeline) == {'fluents', 'events', 'quantities', 'meta', 'vocabulary'}
    for name, args, start, end in timeline['fluents'] + timeline['events']:
        assert isinstance(name, str) and all(isinstance(a, str) for a in args)
        assert 0.0 <= start <= end <= timeline['meta']['duration']
    assert timeline['meta']['program'] == 'grasp_object'
    assert timeline['meta']['params'] == {'force': 5.0, 'position': 0.0, 'lift_time': 1.0}
    fluents = {(f[0], tuple(f[1])) for f in timeline['fluents']}
    assert {('contact', ('egg1', 'table1')), ('supported_by', ('egg1', 'table1')),
            ('on', ('egg1', 'table1')), ('in_gripper', ('egg1',)),
            ('contact', ('egg1', 'pr2_robot'))} <= fluents


def held_egg_timeline(offset, release_at=None):
    """The timeline of an egg held between two fingers that moves by ``offset`` (x, y, z in
    the world, the fingers' frame) between 0.5 s and 1 s, and leaves the fingers at
    ``release_at`` [s] if given, while the gripper stays closed."""
    from projection_server.timeline.rules import Rules
    from projection_server.timeline.samples import Gripper, Poses, Sample

    eye = np.eye(3)
    samples = []
    for i in range(120):
        t = i / 60
        s = min(max((t - 0.5) / 0.5, 0.0), 1.0)
        egg = np.array([0.0, 0.0, 1.0]) + s * np.asarray(offset)
        held = release_at is None or t < release_at
        contacts = ([('egg1', '', 'g', 'l', 5.0, (0.0, -1.0, 0.0)),
                     ('egg1', '', 'g', 'r', 5.0, (0.0, 1.0, 0.0))] if held else [])
        poses = Poses()
        for name, pose in {'egg1': (egg, eye), 'g/l': (np.array([0.0, 0.02, 1.0]), eye),
                           'g/r': (np.array([0.0, -0.02, 1.0]), eye),
                           'g': (np.array([0.0, 0.0, 1.1]), eye)}.items():
            poses.setdefault(name, pose)
        gripper = Gripper(command='close', finger_links=['l', 'r'])
        samples.append(Sample(t, poses=poses, moving={'egg1', 'g'}, contacts=contacts,
                              grippers={'g': gripper}))
    from projection_server.simulation import load_settings

    timeline = Rules(samples, load_settings().timeline)
    return [e for e in timeline.events() if e[0] in ('slip', 'shift')]


def test_an_egg_that_moves_within_the_grasp_shifts():
    (shift,) = held_egg_timeline((0.008, 0.0, 0.0))
    assert shift[0] == 'shift' and 0.5 <= shift[2] < shift[3] <= 1.0


def test_an_egg_that_sinks_between_the_fingers_and_stays_sunk_slips():
    (slip,) = held_egg_timeline((0.0, 0.0, -0.008))
    assert slip[0] == 'slip' and 0.5 <= slip[2] < slip[3] <= 1.0


def test_an_egg_that_leaves_the_closed_fingers_slips():
    (slip,) = held_egg_timeline((0.0, 0.0, 0.0), release_at=1.5)
    assert slip[0] == 'slip' and slip[2] == slip[3] == pytest.approx(1.5 - 1 / 60)


def test_a_small_sag_is_neither_slip_nor_shift():
    assert held_egg_timeline((0.0, 0.0, -0.003)) == []
