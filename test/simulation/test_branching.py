"""Projections that share their first steps, stepped once and forked where they part
(:mod:`projection_server.simulation.branching`): the same bags and timelines as projections
run one by one, through the pool's trees, paused for other queries, their failures and
their cancellation."""

from __future__ import annotations

import concurrent.futures
import copy
import gc
import logging
import os
from pathlib import Path
import signal
import time

import pytest
import yaml

from projection_server import projection
from projection_server.simulation import Job, load_settings, ProjectionError
from projection_server.simulation import branching
from projection_server.simulation.branching import run_tree, start_tree
from projection_server.simulation.runner import Projection, Simulator
from projection_server.timeline import translate_records
from projection_server.workers.bag_store import BagStore
from projection_server.workers.local import WorkerPool
from projection_server.workers.run import project

from .conftest import PANDA

# The pouring scenario with a small batter: forty particles pour in well under a second.
SMALL = yaml.safe_load((Path(__file__).parent / 'pouring.yaml').read_text())
SMALL['entities'][1]['parts'][0]['properties']['particle_count'] = 40
# Two angles and two holding times: the tree parts first where the smaller angle is reached.
FAMILY = [{'angle': a, 'time': t, 'position': 0.0} for t in (0.2, 0.4) for a in (1.9, 2.1)]


def jobs(family=FAMILY, position=0.0):
    return [Job.checked(SMALL, 'pour', {**p, 'position': position}) for p in family]


def files(bag: str | Path) -> dict[str, bytes]:
    return {f.name: f.read_bytes() for f in sorted(Path(bag).iterdir())}


def without_bag(timeline: dict) -> dict:
    return {**timeline, 'meta': {k: v for k, v in timeline['meta'].items() if k != 'bag'}}


@pytest.fixture(scope='module')
def straight(tmp_path_factory):
    """The family's projections, each run from the start: bag files and timeline by key."""
    settings, simulator = load_settings(), Simulator()
    runs = {}
    try:
        for job in jobs():
            key = job.key(settings)
            bag = tmp_path_factory.mktemp('straight') / BagStore.name(job, key)
            runs[key] = files_of(bag, project(simulator, job, settings, bag))
    finally:
        simulator.close()
    return runs


def files_of(bag: Path, timeline: dict) -> tuple[dict[str, bytes], dict]:
    return files(bag), without_bag(timeline)


def test_a_tree_gives_each_leaf_the_bag_and_timeline_of_its_straight_run(straight, tmp_path):
    settings, simulator = load_settings(), Simulator()
    reports = []
    leaves = []
    for job in jobs():
        key = job.key(settings)
        (tmp_path / key).mkdir()
        leaves.append((job, tmp_path / key / BagStore.name(job, key)))
    try:
        complete = run_tree(simulator.client, leaves, settings,
                            lambda index, result, ok: reports.append((index, result, ok)))
    finally:
        simulator.close()
    # Reports come from the forked leaves; in this process they are lost, so each leaf's
    # bag is what shows it ran.
    assert complete and reports == []
    for job, bag in leaves:
        assert files(bag) == straight[job.key(settings)][0]


def test_a_trees_process_group_can_be_paused_as_soon_as_it_is_started(tmp_path):
    # A worker pauses its tree (SIGSTOP to the tree's group) for another query's projection
    # that may come at once: the group must exist when start_tree returns.
    settings, simulator = load_settings(), Simulator()
    job = jobs()[0]
    try:
        for attempt in range(20):
            bag = tmp_path / str(attempt) / BagStore.name(job, job.key(settings))
            bag.parent.mkdir()
            pid = start_tree(simulator.client, [(job, bag)], settings,
                             lambda index, result, ok: None)
            os.killpg(pid, signal.SIGSTOP)
            os.killpg(pid, signal.SIGCONT)
            os.killpg(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
    finally:
        simulator.close()


def test_a_family_submitted_together_runs_as_one_tree_with_the_same_results(
        straight, tmp_path, caplog):
    caplog.set_level(logging.DEBUG, logger='projection_server.workers.local.pool')
    settings = load_settings()
    with WorkerPool(tmp_path, workers=1) as pool:
        results = [f.result(timeout=120.0) for f in pool.submit_all(jobs(), 60.0)]
    assert 'a tree of 4 projections' in caplog.text
    for job, result in zip(jobs(), results):
        assert Path(result.bag).name == BagStore.name(job, job.key(settings))
        assert (files(result.bag), without_bag(result.timeline)) == straight[job.key(settings)]


def test_two_workers_share_one_family_between_them(tmp_path, caplog):
    caplog.set_level(logging.DEBUG, logger='projection_server.workers.local.pool')
    with WorkerPool(tmp_path, workers=2) as pool:
        for future in pool.submit_all(jobs(), 60.0):
            assert os.path.isdir(future.result(timeout=120.0).bag)
    assert caplog.text.count('a tree of 2 projections') == 2


def test_a_tree_whose_worker_dies_runs_what_it_had_not_finished_one_by_one(straight,
                                                                            tmp_path):
    settings = load_settings()
    with WorkerPool(tmp_path, workers=1) as pool:
        worker, futures, tree = _tree_under_way(pool)
        os.kill(worker, signal.SIGKILL)
        results = [f.result(timeout=120.0) for f in futures]
        assert pool.worker_pids != [worker]
    for job, result in zip(jobs(), results):
        assert (files(result.bag), without_bag(result.timeline)) == straight[job.key(settings)]
    # The tree's processes died with the worker.
    deadline = time.monotonic() + 10.0
    while any(os.path.exists(f'/proc/{pid}') for pid in tree):
        assert time.monotonic() < deadline, 'a process of the tree outlived its worker'
        time.sleep(0.05)


def test_another_querys_projection_runs_while_the_tree_waits_and_changes_no_byte(
        straight, tmp_path, make_scenario):
    settings = load_settings()
    grasp = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0, 'position': 0.0})
    with WorkerPool(tmp_path, workers=1) as pool:
        worker, futures, _ = _tree_under_way(pool, 'q/grid')
        quick = pool.submit(grasp, 60.0, owner='q/quick')
        assert os.path.isdir(quick.result(timeout=60.0).bag)
        # One worker: the grasp did not wait for the whole tree.
        assert not all(f.done() for f in futures)
        results = [f.result(timeout=120.0) for f in futures]
        assert pool.worker_pids == [worker]
    for job, result in zip(jobs(), results):
        assert (files(result.bag), without_bag(result.timeline)) == straight[job.key(settings)]


def test_cancelling_a_trees_owner_stops_it_and_the_pool_serves_on(tmp_path):
    with WorkerPool(tmp_path, workers=1) as pool:
        _, futures, _ = _tree_under_way(pool, 'q/tree')
        assert pool.cancel('q/tree') == 4
        _all_fail(futures, 'cancelled')
        assert os.path.isdir(pool.run(jobs()[0], timeout=60.0))


def test_dropping_a_trees_only_owner_stops_what_it_has_not_made(tmp_path):
    with WorkerPool(tmp_path, workers=1) as pool:
        _, futures, _ = _tree_under_way(pool, 'q/once')
        wanted = pool.submit(jobs()[3], 60.0, owner='q/other')
        # The tree goes on for the one another owner still wants.
        assert pool.cancel('q/once', running=False) == 3
        assert os.path.isdir(wanted.result(timeout=120.0).bag)
        assert pool.cancel('q/other', running=False) == 0
        made = [f for f in futures if f.exception(timeout=60.0) is None]
        assert futures[3] in made


def test_a_tree_over_its_time_limit_fails_each_projection_with_its_own_timeout(tmp_path):
    with WorkerPool(tmp_path, workers=1) as pool:
        _all_fail(pool.submit_all(jobs()[:2], 0.05), 'timeout')
        assert os.path.isdir(pool.run(jobs()[0], timeout=60.0))


def test_the_prefetch_plan_queues_whole_families_and_depth_ahead_otherwise(monkeypatch):
    turns = [{'angle': a} for a in (0.1, 0.3, 0.5, 0.7, 0.9)]   # a program that shares nothing
    assert projection.prefetch_plan('turn_pancake', turns, 2) == [[0, 1, 2], [3], [4], [], []]
    # On MuJoCo, grasps share all but their force: two positions' families, then the third's.
    grasps = [{'force': f, 'position': x} for x in (0.0, 0.02, -0.02) for f in (1, 5)]
    assert projection.prefetch_plan('grasp_object', grasps, 1, {'engine': 'mujoco'}) == [
        [0, 1, 2, 3], [], [4, 5], [], [], []]
    pours = [{'angle': a, 'time': 0.5, 'position': x} for x in (0.0, 0.02, 0.04, 0.06)
             for a in (1.9, 2.0)]
    # Position slowest: the families of the first three positions at once, then the fourth.
    assert projection.prefetch_plan('pour', pours, 2) == [[0, 1, 2, 3, 4, 5], [], [6, 7], [],
                                                          [], [], [], []]
    # Positions fastest: the same families, their members spread over the enumeration.
    spread = [{'angle': a, 'time': 0.5, 'position': x} for a in (1.9, 2.0)
              for x in (0.0, 0.02, 0.04)]
    assert projection.prefetch_plan('pour', spread, 1) == [[0, 3, 1, 4], [2, 5], [], [], [],
                                                           []]
    many = [{'angle': 1.0 + i / 100, 'time': 0.5, 'position': 0.0} for i in range(70)]
    plan = projection.prefetch_plan('pour', many, 1)
    assert [len(p) for p in plan if p] == [64, 6]   # batches of FAMILY_BATCH
    assert sorted(i for p in plan for i in p) == list(range(70))
    # The ray backend runs families as trees too.
    monkeypatch.setitem(projection._config, 'backend', 'ray')
    assert projection.prefetch_plan('pour', pours, 2) == [[0, 1, 2, 3, 4, 5], [], [6, 7], [],
                                                          [], [], [], []]


def _all_fail(futures, kind: str) -> None:
    for future in futures:
        with pytest.raises(ProjectionError) as info:
            future.result(timeout=120.0)
        assert info.value.kind == kind


def _tree_under_way(pool: WorkerPool, owner: str | None = None):
    """The family submitted to the pool's one worker once it is warm: the worker's pid, the
    futures and the tree's processes, once they run."""
    worker = _warm_worker(pool)
    futures = pool.submit_all(jobs(), 60.0, owner=owner)
    return worker, futures, _descendants(worker, deadline=time.monotonic() + 30.0)


def _warm_worker(pool: WorkerPool) -> int:
    """The pid of the pool's one worker, once it has warmed up."""
    deadline = time.monotonic() + 60.0
    while pool.warm_ups[0] is None:
        assert time.monotonic() < deadline, 'the worker did not start'
        time.sleep(0.01)
    return pool.worker_pids[0]


def _descendants(pid: int, deadline: float) -> set[int]:
    """The processes below ``pid`` once it has forked some (a tree under way)."""
    while True:
        found = _below(pid)
        if found:
            return found
        assert time.monotonic() < deadline, 'no tree started'
        time.sleep(0.005)


def _below(pid: int) -> set[int]:
    """The processes below ``pid`` now."""
    children = {}
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            try:
                stat = Path(f'/proc/{entry}/stat').read_text()
            except OSError:
                continue
            children.setdefault(int(stat.rsplit(')', 1)[1].split()[1]), []).append(int(entry))
    found, todo = set(), [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.add(child)
            todo.append(child)
    return found


# A plan's parametrizations (Table I's grasp plan at three forces, on the pr2 gripper) part
# where close_gripper's force first acts: the approach before it is stepped once.
PLAN = [{'action': 'move_to', 'object': 'egg1', 'offset': [-0.09, 0, 0],
         'orientation': ['side', 0.0], 'speed': 2.0},
        {'action': 'move_to', 'object': 'egg1', 'offset': [0, 0, 0], 'speed': 0.15},
        {'action': 'close_gripper', 'force': {'param': 'force'}},
        {'action': 'wait', 'seconds': 0.3},
        {'action': 'move_by', 'offset': [0, 0, 0.1]}]


def test_a_plans_parametrizations_run_as_a_tree_with_the_bags_of_their_straight_runs(
        make_scenario, tmp_path, caplog):
    caplog.set_level(logging.DEBUG, logger='projection_server.workers.local.pool')
    settings, simulator = load_settings(), Simulator()
    plan_jobs = [Job.checked(make_scenario(), 'plan', {'force': f}, None, PLAN)
                 for f in (1.0, 5.0, 11.0)]
    assert len({job.family(settings) for job in plan_jobs}) == 1
    results = _as_tree_and_straight(plan_jobs, settings, simulator, tmp_path, caplog)
    outcomes = [{e[0] for e in result.timeline['events']} for result in results]
    assert 'slip' in outcomes[0] and 'lift' in outcomes[1] and 'slip' not in outcomes[1]


# The Panda's top grasp and lift (the robot loop's plan), parted where its force first acts.
TOP_PLAN = [{'action': 'move_to', 'object': 'egg1', 'offset': [0, 0, 0.10],
             'orientation': 'top', 'speed': 0.5},
            {'action': 'move_to', 'object': 'egg1', 'offset': [0, 0, 0], 'speed': 0.1},
            {'action': 'close_gripper', 'force': {'param': 'force'}},
            {'action': 'wait', 'seconds': 0.3},
            {'action': 'move_by', 'offset': [0, 0, 0.1]},
            {'action': 'wait', 'seconds': 0.5}]


def test_a_urdf_arms_plan_runs_as_a_tree_of_mujoco_copies_with_the_bags_of_its_straight_runs(
        make_scenario, tmp_path, caplog):
    # A URDF arm's world copies with its projection, but its inverse kinematics (a PyBullet
    # client of the process) is shared by the copies: each copy's plan solves in it.
    caplog.set_level(logging.DEBUG, logger='projection_server.workers.local.pool')
    settings, simulator = load_settings(), Simulator()
    scenario = make_scenario()
    scenario['entities'][1] = copy.deepcopy(PANDA)
    plan_jobs = [Job.checked(scenario, 'plan', {'force': f}, {'engine': 'mujoco'}, TOP_PLAN)
                 for f in (12.0, 1.0, 5.0)]   # breaks in the first copy, slips, lifts
    assert len({job.family(settings) for job in plan_jobs}) == 1
    results = _as_tree_and_straight(plan_jobs, settings, simulator, tmp_path, caplog)
    outcomes = [{e[0] for e in result.timeline['events']} for result in results]
    assert 'break' in outcomes[0] and 'slip' in outcomes[1], outcomes
    assert 'lift' in outcomes[2] and not {'slip', 'break'} & outcomes[2], outcomes


def test_a_collected_copy_of_a_urdf_arms_projection_leaves_the_original_its_solver(
        make_scenario, tmp_path):
    # A copy that shared the arm's PyBullet solver by copying its client disconnected it
    # when collected: the original's next move failed ('Not connected to physics server').
    settings, simulator = load_settings(), Simulator()
    scenario = make_scenario()
    scenario['entities'][1] = copy.deepcopy(PANDA)
    job = Job.checked(scenario, 'plan', {'force': 5.0}, {'engine': 'mujoco'}, TOP_PLAN)
    try:
        straight = project(simulator, job, settings, tmp_path / 'straight')
        log = branching._SharedLog()
        projection = Projection(simulator, job, settings, log)
        projection.advance(int(1.0 * settings.physics.rate_hz))   # before the last moves
        copied, _ = branching._copied(projection, log)
        copied.advance()
        del copied
        gc.collect()
        projection.advance()
    finally:
        simulator.close()
    ours = translate_records(projection.monitor.records, tmp_path / 'straight',
                             projection.scenario)
    assert ours == straight


def test_grasps_that_differ_in_their_force_share_their_approach_on_mujoco_only(
        make_scenario, tmp_path, caplog):
    # The grasp's force acts only when its fingers close: the world's build, the egg's
    # settling and the approach are stepped once for every force, and each force goes on
    # in a copy of the MuJoCo world. A fork of a PyBullet worker costs what they share.
    caplog.set_level(logging.DEBUG, logger='projection_server.workers.local.pool')
    settings, simulator = load_settings(), Simulator()
    engine = 'mujoco'
    on_pybullet = Job.checked(make_scenario(), 'grasp_object', {'force': 1.0})
    assert on_pybullet.family(settings) is None
    assert projection.prefetch_plan('grasp_object', [{'force': 1.0}, {'force': 5.0}], 0) == [
        [0], [1]]
    assert projection.prefetch_plan('grasp_object', [{'force': 1.0}, {'force': 5.0}], 0,
                                    {'engine': engine}) == [[0, 1], []]
    forces = (11.0, 1.0, 5.0)   # the egg breaks in the first copy: the others' stays whole
    grasp_jobs = [Job.checked(make_scenario(), 'grasp_object', {'force': f, 'position': 0.0},
                              {'engine': engine}) for f in forces]
    other = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0, 'position': 0.02},
                        {'engine': engine})
    assert len({job.family(settings) for job in grasp_jobs}) == 1
    assert other.family(settings) != grasp_jobs[0].family(settings)   # placed elsewhere
    results = _as_tree_and_straight(grasp_jobs, settings, simulator, tmp_path, caplog)
    outcomes = [{e[0] for e in result.timeline['events']} for result in results]
    assert 'break' in outcomes[0] and 'slip' in outcomes[1] and not {'slip', 'break'} & outcomes[2]


def test_a_mujoco_tree_forks_nothing_and_answers_another_querys_projection_between_leaves(
        make_scenario, tmp_path, caplog):
    # Where the worlds copy, the worker runs a tree itself (no fork, no pages copied), and
    # takes another query's projection after the leaf under way, not after the tree.
    caplog.set_level(logging.DEBUG, logger='projection_server.workers.local.pool')
    family = _slow_mujoco_family(make_scenario)
    quick = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0, 'position': 0.02},
                        {'engine': 'mujoco'})
    with WorkerPool(tmp_path, workers=1) as pool:
        worker = _warm_worker(pool)
        futures = pool.submit_all(family, 120.0, owner='q/grid')
        answered = pool.submit(quick, 60.0, owner='q/quick')
        assert os.path.isdir(answered.result(timeout=120.0).bag)
        assert not all(f.done() for f in futures)   # it did not wait for the whole tree
        assert _below(worker) == set()
        results = [f.result(timeout=240.0) for f in futures]
        assert pool.worker_pids == [worker]
    assert 'a tree of 4 projections' in caplog.text
    outcomes = [{e[0] for e in result.timeline['events']} for result in results]
    assert not any({'slip', 'break'} & o for o in outcomes), outcomes   # 3-6 N hold it


def test_cancelling_a_mujoco_trees_owner_stops_it_and_the_pool_serves_on(make_scenario,
                                                                         tmp_path):
    # The tree runs in the worker's process: cancelling stops the worker with it, and what
    # the tree had not answered fails as cancelled.
    family = _slow_mujoco_family(make_scenario)
    with WorkerPool(tmp_path, workers=1) as pool:
        worker = _warm_worker(pool)
        futures = pool.submit_all(family, 120.0, owner='q/tree')
        concurrent.futures.wait(futures, timeout=120.0,
                                return_when=concurrent.futures.FIRST_COMPLETED)
        assert pool.cancel('q/tree') >= 1
        kinds = []
        for future in futures:
            error = future.exception(timeout=120.0)
            kinds.append(None if error is None else error.kind)
        assert None in kinds and 'cancelled' in kinds and set(kinds) <= {None, 'cancelled'}
        quick = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0},
                            {'engine': 'mujoco'})
        assert os.path.isdir(pool.run(quick, timeout=60.0))
        assert pool.worker_pids != [worker]


def _slow_mujoco_family(make_scenario) -> list[Job]:
    """Four MuJoCo grasps at one position (a family) at 960 Hz: about half a second each."""
    return [Job.checked(make_scenario(), 'grasp_object', {'force': f, 'position': 0.0},
                        {'engine': 'mujoco', 'rate_hz': 960}) for f in (3.0, 4.0, 5.0, 6.0)]


def _as_tree_and_straight(family, settings, simulator, tmp_path, caplog):
    """The results of ``family``'s jobs through a pool, which runs them as one tree, each
    checked against the job's straight run (bag files and timeline)."""
    straight = {}
    try:
        for job in family:
            key = job.key(settings)
            bag = tmp_path / 'straight' / key / BagStore.name(job, key)
            straight[key] = files_of(bag, project(simulator, job, settings, bag))
    finally:
        simulator.close()
    with WorkerPool(tmp_path / 'pool', workers=1) as pool:
        results = [f.result(timeout=120.0) for f in pool.submit_all(family, 60.0)]
    assert f'a tree of {len(family)} projections' in caplog.text
    for job, result in zip(family, results):
        assert (files(result.bag), without_bag(result.timeline)) == straight[job.key(settings)]
    return results
