"""Plans written in the query, projected through the real service: the README's grasp plan
against the built-in grasp, the paper's section II drop, and every bad plan refused with a
clear error while the node serves on. What a plan does (a grasp, a carry, a release, an
unreachable pose) is projected on both engines alike."""

from __future__ import annotations

import json
from pathlib import Path
import re

from projection_interfaces.srv import PrologQuery
import pytest

Q = PrologQuery.Request
SIM_TIMEOUT = 120.0
TUTORIAL = Path(__file__).resolve().parents[1] / 'docs' / 'tutorials' / 'own_task.md'
OUTCOME = ('( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip '
           '; O = ok )')
ENGINES = ('pybullet', 'mujoco')


def ask(call, text, timeout=SIM_TIMEOUT):
    r = call(PrologQuery, 'query', Q(mode=Q.ALL_SOLUTIONS, query=text, timeout=timeout,
                                     max_solutions=100), timeout=timeout * 4)
    return r, [json.loads(s) for s in r.solutions]


def readme_grasp_plan() -> str:
    """The tutorial's plan that does what grasp_object does (its make_projection goal)."""
    text = TUTORIAL.read_text()
    match = re.search(r'```\{code-block\} prolog\n:name: grasp-plan\n'
                      r'(make_projection\(grasping, plan\(.*?\))\n```', text, re.S)
    assert match, 'the tutorial shows no grasp plan'
    return match.group(1)


def on(engine, goal):
    """``goal``, a make_projection/4 ending in ``, TL)``, on ``engine`` (make_projection/5;
    as written on the default engine)."""
    if engine == 'pybullet':
        return goal
    assert goal.endswith(', TL)'), goal
    return goal[:-len(', TL)')] + f', [physics(_{{engine: {engine}}})], TL)'


@pytest.mark.parametrize('engine', ENGINES)
def test_the_readmes_grasp_plan_agrees_with_the_built_in_grasp_on_table_i(call, engine):
    plan = readme_grasp_plan()
    r, planned = ask(call, f'{on(engine, plan)}, {OUTCOME}')
    assert r.ok, r.message
    r, built_in = ask(call, on(engine, '''make_projection(grasping, grasp_object,
        [(F, force, [1, 3, 5, 7, 9, 11]), (P, position, [-0.02, 0.0, 0.02])], TL)''')
                      + ', ' + OUTCOME)
    assert r.ok, r.message
    cells = {(s['F'], s['P']): s['O'] for s in built_in}
    assert len(cells) == len(planned) == 18
    agree = sum(cells[(s['F'], s['P'])] == s['O'] for s in planned)
    assert agree >= 17, (planned, built_in)
    # and the outcomes span the table: slip, ok and break all occur
    assert {s['O'] for s in planned} == {'slip', 'ok', 'break'}


DROP = '''make_projection(grasping, plan([
    move_to(egg1, [-0.09, 0, 0], [orientation(side(0)), speed(2.0)]),
    move_to(egg1, [0, 0, 0], [speed(0.15)]), close_gripper(5), wait(0.3),
    move_by([0, 0, 0.1], [speed(0.2)]), move_by([0, Side, 0], [speed(0.3)]),
    move_by([0, 0, Down], [speed(0.2)]), open_gripper, wait(1.0)]),
    [(Side, side, [{side}]), (Down, down, [{down}])], [physics(_{{engine: {engine}}})], _),
    findall(F, ( occurs(Evt, T1), typeOf(Evt, dropping), objOf(Evt, egg1),
                 after(T2, T1), holds(F, T2), objOf(F, egg1) ), Fs0),
    sort(Fs0, Fs)'''


@pytest.mark.parametrize('engine', ENGINES)
def test_an_egg_released_half_a_metre_above_the_floor_is_broken_after_its_drop(call, engine):
    # The tool point 0.522 m high: the egg's lowest point 0.5 m above the floor, beside the
    # table.
    r, sols = ask(call, DROP.format(side=-0.6, down=-0.32, engine=engine))
    assert r.ok, r.message
    assert 'broken(egg1)' in [_text(f) for f in sols[0]['Fs']], sols


@pytest.mark.parametrize('engine', ENGINES)
def test_an_egg_released_a_centimetre_above_the_table_drops_and_stays_whole(call, engine):
    r, sols = ask(call, DROP.format(side=0.0, down=-0.09, engine=engine)
                  + ', once(occurs(drop(egg1), _))')
    assert r.ok, r.message
    facts = [_text(f) for f in sols[0]['Fs']]
    assert 'broken(egg1)' not in facts and 'on(egg1,table1)' in facts, facts


def _text(term) -> str:
    if isinstance(term, dict):
        return f'{term["functor"]}({",".join(_text(a) for a in term["args"])})'
    return str(term)


@pytest.mark.parametrize('plan, kind, words', [
    ('[jump(1)]', 'domain_error', 'plan step'),
    ('[move_to(egg1, [0, 0])]', 'domain_error', 'plan step'),
    ('[move_by([0, 0, 0.1], [speed(1), color(red)])]', 'domain_error', 'plan step'),
    ('[move_to(pose([0, 0, 1], [0, 0, 0, 1]), [orientation(top)])]', 'domain_error',
     'plan step'),
    ('[]', 'domain_error', 'plan has 1 to 100 steps'),
    ('L', 'instantiation_error', ''),
    ('[wait(X)]', 'instantiation_error', ''),
    ('[move_to(unicorn1, [0, 0, 0.1])]', 'existence_error', 'unicorn1'),
    ('[move_by([0, 0, 0.1], [speed(-1)])]', 'domain_error', 'speed'),
    ('[wait(60), wait(60), wait(60)]', 'resource_error', 'simulated time'),
    ('[move_by([0, 0, 0.5], [speed(0.004)])]', 'resource_error', 'at least 125 s'),
])
def test_a_bad_plan_is_refused_before_anything_runs(call, plan, kind, words):
    if plan == '[]':
        words = 'A plan has 1 to 100 steps'
    r, _ = ask(call, f'make_projection(grasping, plan({plan}), [], _)', timeout=20.0)
    assert not r.ok and r.error_kind == kind, (r.error_kind, r.message)
    assert words in r.message, r.message


def test_a_plan_of_more_than_a_hundred_steps_is_refused(call):
    r, _ = ask(call, 'length(L, 101), maplist(=(wait(0.01)), L), '
                     'make_projection(grasping, plan(L), [], _)', timeout=20.0)
    assert not r.ok and r.error_kind == 'domain_error', r.message
    assert '101' in r.message


@pytest.mark.parametrize('engine', ENGINES)
def test_a_pose_out_of_the_robots_reach_is_an_unreachable_projection_error(call, engine):
    r, _ = ask(call, 'make_projection(grasping, plan([move_to(pose([4.0, 0, 1], [0, 0, 0, 1]))]),'
                     f' [], [physics(_{{engine: {engine}}})], _)')
    assert not r.ok and r.error_kind == 'projection_error', r.message
    assert 'unreachable' in r.message and 'pr2_robot' in r.message, r.message
    r, sols = ask(call, 'X = 1')   # the node serves on
    assert r.ok and sols == [{'X': 1}]


@pytest.mark.parametrize('engine', ENGINES)
def test_a_plans_parameters_have_any_name_and_negative_values(call, engine):
    r, sols = ask(call, f'''make_projection(grasping,
        plan([move_to(egg1, [Dx, 0, Up], [orientation(top), speed(1.0)]), wait(0.1)]),
        [(Dx, sideways, [-0.05]), (Up, height, [0.2])], [physics(_{{engine: {engine}}})], TL),
        quantity(displacement(egg1), D, TL)''')
    assert r.ok, r.message
    assert sols[0]['Dx'] == -0.05 and sols[0]['D'] < 0.005


# The README's plans at the default speed (0.1 m/s): no plan a user writes is refused as long.
PICK_AND_PLACE = ('make_projection(grasping, plan([move_to(egg1, [-0.09, 0, 0], '
                  '[orientation(side(0))]), move_to(egg1, [0, 0, 0]), close_gripper(5), '
                  'move_by([0, 0, 0.1]), move_by([0, -0.3, 0]), move_by([0, 0, -0.05]), '
                  'open_gripper]), [], [physics(_{{engine: {engine}}})], TL), '
                  'quantity(final_pose(egg1), [[X, Y, Z], _], TL)')


@pytest.mark.parametrize('engine', ENGINES)
def test_a_pick_and_place_at_the_default_speeds_is_projected(call, engine):
    r, sols = ask(call, PICK_AND_PLACE.format(engine=engine))
    assert r.ok, r.message
    # carried 0.3 m to the robot's right and set down on the table
    assert abs(sols[0]['Y'] + 0.3) < 0.03 and abs(sols[0]['Z'] - 0.742) < 0.01, sols


@pytest.mark.parametrize('engine', ENGINES)
def test_the_section_ii_release_at_the_default_speeds_breaks_the_egg(call, engine):
    default_speeds = re.sub(r',\s*\[speed\([0-9.]+\)\]\)', ')', DROP)
    assert 'speed' not in default_speeds.split('open_gripper')[0].split('close_gripper')[1]
    r, sols = ask(call, default_speeds.format(side=-0.6, down=-0.32, engine=engine))
    assert r.ok, r.message
    assert 'broken(egg1)' in [_text(f) for f in sols[0]['Fs']], sols


def test_a_plan_that_runs_past_its_simulated_time_stops_naming_the_step(call):
    # 119 s of waiting cannot be refused before running, but the move after it cannot end
    # in the second left.
    r, _ = ask(call, 'make_projection(grasping, plan([wait(119), move_to(egg1, [0, 0, 0.5]),'
                     ' wait(0.5)]), [], _)')
    assert not r.ok and r.error_kind == 'resource_error', (r.error_kind, r.message)
    assert 'ran past 120 s' in r.message and 'step 2 of 3 (move_to egg1' in r.message, \
        r.message
    r, sols = ask(call, 'X = 1')   # the node serves on
    assert r.ok and sols == [{'X': 1}]
