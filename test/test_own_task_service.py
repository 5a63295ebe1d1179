"""Tasks beyond the paper's, through the real service: the Panda arm grasping an egg over a
force sweep, an explicit URDF robot, a box pushed off the table's edge, a mesh glass
picked up, a heavier mug slipping where a light one holds; each outcome from physics and
the same at a 2x finer step, on both engines (the Panda's finer step on MuJoCo:
test_engines_robots_service)."""

from __future__ import annotations

import json

from projection_interfaces.srv import PrologQuery
import pytest

from test.queries import PUSH_OFF_THE_EDGE

Q = PrologQuery.Request
SIM_TIMEOUT = 120.0
ENGINES = ('pybullet', 'mujoco')


def on(engine, finer=False):
    """The options of a projection on ``engine``, at a 2x finer step if ``finer``."""
    return (f'[physics(_{{engine: {engine}'
            + (', rate_hz: 480, solver_iterations: 200' if finer else '') + '})]')


FINER = on('pybullet', finer=True)
OUTCOME = ('( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip '
           '; O = ok )')
PANDA_GRASP = '''plan([move_to(egg1, [0, 0, 0.10], [orientation(top), speed(0.5)]),
                      move_to(egg1, [0, 0, 0], [speed(0.1)]),
                      close_gripper(F), wait(0.3), move_by([0, 0, 0.1]), wait(1.0)])'''


def ask(call, text, timeout=SIM_TIMEOUT):
    r = call(PrologQuery, 'query', Q(mode=Q.ALL_SOLUTIONS, query=text, timeout=timeout,
                                     max_solutions=100), timeout=timeout * 4)
    assert r.ok, (r.error_kind, r.message)
    return [json.loads(s) for s in r.solutions]


def panda_sweep(call, forces, options='[]'):
    sols = ask(call, f'''create_scenario(S), add_to_scenario(S, [kitchen_env, panda_robot, egg1]),
        make_projection(S, {PANDA_GRASP}, [(F, force, {forces})], {options}, TL), {OUTCOME}''')
    return [(s['F'], s['O']) for s in sols]


@pytest.mark.parametrize('engine', ENGINES)
def test_the_panda_grasps_an_egg_slipping_then_holding_then_breaking_it_as_force_grows(
        call, engine):
    outcomes = [o for _, o in panda_sweep(call, [0.25, 1, 3, 5, 7, 9, 11, 13], on(engine))]
    assert set(outcomes) == {'slip', 'ok', 'break'}, outcomes
    order = {'slip': 0, 'ok': 1, 'break': 2}
    assert [order[o] for o in outcomes] == sorted(order[o] for o in outcomes), outcomes


def test_the_pandas_outcomes_stay_at_a_2x_finer_step(call):
    assert panda_sweep(call, [1, 5, 11], FINER) == panda_sweep(call, [1, 5, 11])


@pytest.mark.parametrize('engine', ENGINES)
def test_a_urdf_robot_given_by_its_facts_grasps_as_the_knowledge_bases_panda(call, engine):
    sols = ask(call, f'''create_scenario(S), add_to_scenario(S, [kitchen_env, egg1,
        entity(arm1, robot, _{{model: urdf, file: "franka_panda/panda.urdf",
                               tool_link: panda_hand, tool_offset: [0, 0, 0.1034],
                               finger_joints: [panda_finger_joint1, panda_finger_joint2],
                               max_force: 20, home: [0, -0.785, 0, -2.356, 0, 1.571, 0.785],
                               pose: _{{xyz: [-0.68, 0, 0.72]}}}})]),
        make_projection(S, {PANDA_GRASP}, [(F, force, [5])], {on(engine)}, TL), {OUTCOME}''')
    assert [s['O'] for s in sols] == ['ok']


@pytest.mark.parametrize('engine', ENGINES)
def test_a_urdf_robot_without_its_tool_link_is_a_clear_error(call, engine):
    r = call(PrologQuery, 'query', Q(mode=Q.ONCE, timeout=60.0, query=f'''create_scenario(S),
        add_to_scenario(S, [kitchen_env, egg1, entity(arm1, robot, _{{model: urdf,
            file: "franka_panda/panda.urdf", tool_link: wrist, tool_offset: [0, 0, 0.1],
            finger_joints: [panda_finger_joint1], max_force: 20}})]),
        make_projection(S, plan([wait(0.1)]), [], {on(engine)}, _)'''), timeout=120.0)
    assert not r.ok and r.error_kind == 'projection_error', r.message
    assert 'wrist' in r.message and 'panda.urdf' in r.message, r.message


@pytest.mark.parametrize('engine', ENGINES)
def test_a_pose_the_panda_cannot_reach_is_unreachable(call, engine):
    r = call(PrologQuery, 'query', Q(mode=Q.ONCE, timeout=60.0, query=f'''create_scenario(S),
        add_to_scenario(S, [kitchen_env, panda_robot]),
        make_projection(S, plan([move_to(pose([0.6, 0, 0.75], [1, 0, 0, 0]))]), [],
                        {on(engine)}, _)'''), timeout=120.0)
    assert not r.ok and r.error_kind == 'projection_error', r.message
    assert 'unreachable' in r.message and 'panda_robot' in r.message, r.message


PUSH = PUSH_OFF_THE_EDGE + ''',
    quantity(displacement(box1), Moved, TL)'''


def push(call, distances, options='[]'):
    sols = ask(call, PUSH.format(distances=distances, options=options))
    return {s['D']: (s['Fell'], s['Moved']) for s in sols}


@pytest.mark.parametrize('engine', ENGINES)
def test_a_box_pushed_past_the_tables_edge_falls_and_not_before(call, engine):
    # The box's centre is 0.15 m from the edge; the fingers touch it after 0.04 m.
    results = push(call, [0.05, 0.1, 0.15, 0.25, 0.3], on(engine))
    fell = [results[d][0] for d in (0.05, 0.1, 0.15, 0.25, 0.3)]
    assert fell == ['no', 'no', 'no', 'yes', 'yes'], results
    assert results[0.05][1] < results[0.1][1] < results[0.15][1] < 0.15 < results[0.25][1]


def test_the_push_falls_the_same_at_a_2x_finer_step(call):
    finer = push(call, [0.1, 0.3], FINER)
    assert [finer[d][0] for d in (0.1, 0.3)] == ['no', 'yes'], finer


GLASS = '''create_scenario(S), add_to_scenario(S, [kitchen_env, pr2_robot, glass1]),
    make_projection(S, plan([open_gripper,
        move_to(glass1, [0, -0.12, 0.03], [orientation(side(pi/2)), speed(1.0),
                                           angular_speed(3)]),
        move_to(glass1, [0, 0, 0.03], [speed(0.1)]), close_gripper(10), wait(0.3),
        move_by([0, 0, 0.1]), wait(1.0)]), [], {options}, TL),
    findall(E, occurs(E, _, TL), Es), quantity(lift_height(glass1), H, TL)'''


@pytest.mark.parametrize('options', [on(e, finer) for e in ENGINES for finer in (False, True)])
def test_a_mesh_glass_is_picked_up_and_lifted(call, options):
    (sol,) = ask(call, GLASS.format(options=options))
    names = [e['functor'] if isinstance(e, dict) else e for e in sol['Es']]
    assert 'grasp' in names and 'lift' in names and 'slip' not in names, sol['Es']
    assert sol['H'] == pytest.approx(0.1, abs=0.01)


MUG = '''create_scenario(S), add_to_scenario(S, [kitchen_env, pr2_robot, mug1]),
    scenario_set_property(S, mug1, mass, {mass}),
    make_projection(S, plan([open_gripper,
        move_to(mug1, [0, -0.12, 0.05], [orientation(side(pi/2)), speed(1.0),
                                         angular_speed(3)]),
        move_to(mug1, [0, 0, 0.05], [speed(0.1)]), close_gripper(8), wait(0.3),
        move_by([0, 0, 0.1]), wait(1.0)]), [], {options}, TL), {outcome}'''


@pytest.mark.parametrize('options', [on(e, finer) for e in ENGINES for finer in (False, True)])
def test_a_heavier_mug_slips_at_a_force_that_holds_a_light_one(call, options):
    (light,) = ask(call, MUG.format(mass=0.3, outcome=OUTCOME, options=options))
    (heavy,) = ask(call, MUG.format(mass=1.2, outcome=OUTCOME, options=options))
    assert (light['O'], heavy['O']) == ('ok', 'slip')
