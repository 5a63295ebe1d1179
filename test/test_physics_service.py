"""Physics settings chosen by a query (make_projection/5's physics option), through the
real service: checked against their ranges, recorded in the bag, part of the cache key; the
textbook's friction thresholds of a grasp hold at every rate on both engines."""

from __future__ import annotations

import json

from projection_interfaces.srv import PrologQuery
import pytest

Q = PrologQuery.Request
SIM_TIMEOUT = 120.0
ENGINES = ('pybullet', 'mujoco')


def ask(call, text, mode=Q.ALL_SOLUTIONS):
    r = call(PrologQuery, 'query', Q(mode=mode, query=text, timeout=SIM_TIMEOUT),
             timeout=SIM_TIMEOUT * 3)
    return r, [json.loads(s) for s in r.solutions]


def bag_settings(path):
    from rosbags.highlevel import AnyReader
    from projection_server.bags import typestore
    with AnyReader([path], default_typestore=typestore()) as reader:
        connections = [c for c in reader.connections if c.topic == '/projection/info']
        for conn, _, raw in reader.messages(connections):
            return json.loads(reader.deserialize(raw, conn.msgtype).settings_json)


def test_a_querys_physics_settings_are_used_and_recorded_in_the_bag(call):
    from pathlib import Path
    r, sols = ask(call, '''
        simulate(grasping, grasp_object, [(_, force, [5])], [], Default),
        simulate(grasping, grasp_object, [(_, force, [5])],
                 [physics(_{rate_hz: 480, solver_iterations: 150}), timeout(90)], Finer),
        projection_physics_setting(grasp_object, rate_hz, S),
        get_dict(default, S, Rate),
        simulate(grasping, grasp_object, [(_, force, [5])],
                 [physics(_{rate_hz: Rate})], Same)''', mode=Q.ONCE)
    assert r.ok, r.message
    default, finer, same = (sols[0][k] for k in ('Default', 'Finer', 'Same'))
    assert same == default != finer
    recorded = bag_settings(Path(finer))
    assert recorded['physics']['rate_hz'] == 480
    assert recorded['physics']['solver_iterations'] == 150
    assert recorded['control'] == {'steps_per_control': 8, 'steps_per_log': 8}   # 60 Hz
    assert bag_settings(Path(default))['physics']['rate_hz'] == sols[0]['Rate']


def test_each_engines_own_defaults_can_be_asked_and_a_projection_runs_with_them(call):
    from pathlib import Path
    r, sols = ask(call, '''
        findall(E-R, ( projection_physics_setting(grasp_object, E, rate_hz, S),
                       get_dict(default, S, R) ), Rates),
        simulate(grasping, grasp_object, [(_, force, [5])], [physics(_{engine: mujoco})],
                 Bag)''', mode=Q.ONCE)
    assert r.ok, r.message
    rates = {pair['args'][0]: pair['args'][1] for pair in sols[0]['Rates']}
    assert rates == {'pybullet': 240, 'mujoco': 120}, rates
    recorded = bag_settings(Path(sols[0]['Bag']))
    assert recorded['physics']['rate_hz'] == 120
    assert recorded['control'] == {'steps_per_control': 2, 'steps_per_log': 2}   # 60 Hz
    r, _ = ask(call, 'projection_physics_setting(grasp_object, ode, rate_hz, S)', mode=Q.ONCE)
    assert not r.ok and r.error_kind == 'domain_error', (r.error_kind, r.message)
    assert all(w in r.message + r.error for w in ('ode', 'pybullet', 'mujoco')), r.message


@pytest.mark.parametrize('options, kind, words', [
    ('[physics(_{rate_hz: 1000})]', 'domain_error', ['rate_hz', 'multiple_of(60)']),
    ('[physics(_{solver_iterations: 0})]', 'domain_error',
     ['solver_iterations', 'between(1,2000)']),
    ('[physics(_{gravity: 3.0})]', 'existence_error', ['gravity']),
    ('[physics(_{solver_iterations: 2.5})]', 'type_error', ['integer']),
    ('[physics(fine)]', 'type_error', ['dict']),
    ('[speed(fast)]', 'domain_error', ['projection_option']),
    ('[timeout(-1)]', 'domain_error', ['positive']),
])
def test_a_bad_option_is_an_error_naming_it(call, options, kind, words):
    r, _ = ask(call, f'make_projection(grasping, grasp_object, [(_, force, [5])], {options}, T)',
               mode=Q.ONCE)
    assert not r.ok and r.error_kind == kind, (r.error_kind, r.message)
    text = r.message + r.error
    assert all(w in text.replace(' ', '') for w in words), text


@pytest.mark.parametrize('engine', ENGINES)
def test_a_quicker_lift_needs_more_friction_at_every_rate(call, engine):
    # Textbook: two pads of 3 N hold the 60 g egg through a minimum-jerk lift of 0.1 m in T
    # seconds iff friction >= m (g + 0.577 / T^2) / 6 N: 0.356 at T = 0.15 s, 0.242 at
    # 0.2 s, 0.134 at 0.4 s. A peak speed of 1.875 x 0.1 m / T, when it holds.
    r, sols = ask(call, f'''
        member(Friction-Lift, [0.25-0.15, 0.25-0.4, 0.35-0.2]), member(Rate, [240, 960]),
        copy_scenario(grasping, S), scenario_set_property(S, egg1, friction, Friction),
        make_projection(S, grasp_object, [(_, force, [3]), (_, lift_time, [Lift])],
                        [physics(_{{engine: {engine}, rate_hz: Rate}})], T),
        ( occurs(slip, _, T) -> Outcome = slip ; Outcome = ok ),
        quantity(max_speed(egg1), Speed, T),
        delete_scenario(S)''')
    assert r.ok, r.message
    assert [(s['Friction'], s['Lift'], s['Rate'], s['Outcome']) for s in sols] == [
        (0.25, 0.15, 240, 'slip'), (0.25, 0.15, 960, 'slip'),
        (0.25, 0.4, 240, 'ok'), (0.25, 0.4, 960, 'ok'),
        (0.35, 0.2, 240, 'ok'), (0.35, 0.2, 960, 'ok')]
    for s in sols:
        if s['Outcome'] == 'ok':
            assert s['Speed'] == pytest.approx(1.875 * 0.1 / s['Lift'], rel=0.05), s


@pytest.mark.parametrize('engine', ENGINES)
def test_whether_a_2_n_grasp_holds_the_egg_does_not_depend_on_the_rate(call, engine):
    # Textbook: two pads of 2 N hold the 60 g egg through the lift from friction 0.156 on.
    # A gantry that jumped to a new target at every control step shook the egg loose below
    # friction 0.21 at 240 Hz and below 0.26 at 960 Hz (bench/RESULTS.md, 2026-11-28).
    r, sols = ask(call, f'''
        member(Friction, [0.13, 0.24]), member(Rate, [240, 960]),
        copy_scenario(grasping, S), scenario_set_property(S, egg1, friction, Friction),
        make_projection(S, grasp_object, [(_, force, [2])],
                        [physics(_{{engine: {engine}, rate_hz: Rate}})], T),
        ( occurs(slip, _, T) -> Outcome = slip ; Outcome = ok ),
        delete_scenario(S)''')
    assert r.ok, r.message
    assert [(s['Friction'], s['Rate'], s['Outcome']) for s in sols] == [
        (0.13, 240, 'slip'), (0.13, 960, 'slip'), (0.24, 240, 'ok'), (0.24, 960, 'ok')]
