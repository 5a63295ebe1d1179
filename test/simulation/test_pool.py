"""The local worker backend: results, timelines, cache, crashes, time limits, warm workers,
cancellation, retention."""

from __future__ import annotations

import os
import signal
import time

import pytest

from projection_server.simulation import Job, ProjectionError
from projection_server.workers.run import translate_bag
from projection_server.workers import Retention, WorkerBackend


def job(make_scenario, force, position=0.0):
    return Job.checked(make_scenario(), 'grasp_object', {'force': force, 'position': position})


def test_a_projection_gives_a_complete_bag_in_the_bag_dir(pool, make_scenario):
    path = pool.run(job(make_scenario, 5.0), timeout=60.0)
    assert os.path.dirname(path) == str(pool.bag_dir)
    assert os.path.isfile(os.path.join(path, 'metadata.yaml'))
    assert not [p for p in pool.bag_dir.iterdir() if p.name.startswith('.tmp-')]


def test_the_local_pool_is_a_worker_backend(pool):
    assert isinstance(pool, WorkerBackend)
    assert pool.workers == 1


def test_the_workers_timeline_is_the_timeline_of_its_bag(pool, make_scenario):
    result = pool.submit(job(make_scenario, 9.0, 0.02), timeout=60.0).result(timeout=60.0)
    from_bag = translate_bag(result.bag)
    assert result.timeline['meta'] == from_bag['meta']
    for part in ('fluents', 'events', 'quantities'):
        assert len(result.timeline[part]) == len(from_bag[part])
        for made, read in zip(result.timeline[part], from_bag[part]):
            assert made == read
    assert ['break', ['egg1']] in [e[:2] for e in result.timeline['events']]


def test_an_identical_projection_comes_from_the_cache(pool, make_scenario):
    first = pool.run(job(make_scenario, 3.0), timeout=60.0)
    mtime = os.stat(os.path.join(first, 'metadata.yaml')).st_mtime_ns
    started = time.monotonic()
    again = pool.submit(job(make_scenario, 3.0), timeout=60.0)
    assert again.done() and again.result().bag == first
    assert time.monotonic() - started < 0.5
    assert os.stat(os.path.join(first, 'metadata.yaml')).st_mtime_ns == mtime


def test_a_worker_killed_mid_projection_fails_it_and_is_replaced(pool, make_scenario):
    pool.run(job(make_scenario, 5.0), timeout=60.0)   # a started worker
    future = pool.submit(job(make_scenario, 4.0), timeout=60.0)
    deadline = time.monotonic() + 30.0
    # Mid-projection: the worker has begun writing the bag in its temporary directory.
    while not any(p.name.startswith('.tmp-') and any(p.iterdir())
                  for p in pool.bag_dir.iterdir()):
        assert time.monotonic() < deadline and not future.done()
        time.sleep(0.005)
    (pid,) = pool.worker_pids
    os.kill(pid, signal.SIGKILL)
    with pytest.raises(ProjectionError) as info:
        future.result(timeout=30.0)
    assert info.value.kind == 'worker_crashed'
    assert os.path.isdir(pool.run(job(make_scenario, 4.0), timeout=60.0))
    assert pool.worker_pids != [pid]


def test_a_projection_over_its_time_limit_is_stopped(pool, make_scenario):
    pool.run(job(make_scenario, 5.0), timeout=60.0)   # start-up does not count
    with pytest.raises(ProjectionError) as info:
        pool.run(job(make_scenario, 6.0), timeout=0.05)
    assert info.value.kind == 'timeout'
    assert os.path.isdir(pool.run(job(make_scenario, 6.0), timeout=60.0))


def test_worker_errors_come_back_as_projection_errors(pool, make_scenario):
    scenario = make_scenario()
    scenario['entities'] = [e for e in scenario['entities'] if e['class'] != 'robot']
    with pytest.raises(ProjectionError) as info:
        pool.run(Job.checked(scenario, 'grasp_object', {}), timeout=60.0)
    assert info.value.kind == 'invalid_scenario'


def test_a_bag_does_not_depend_on_earlier_projections_of_its_worker(
        pool, make_scenario, tmp_path):
    from projection_server.workers.run import run_projection

    pool.run(job(make_scenario, 9.0, 0.02), timeout=60.0)   # leaves a broken egg behind
    pid = pool.worker_pids[0]
    path = pool.run(job(make_scenario, 7.0, -0.02), timeout=60.0)
    assert pool.worker_pids == [pid]   # the same warm worker
    fresh = tmp_path / os.path.basename(path)
    run_projection(job(make_scenario, 7.0, -0.02), pool.settings, fresh)
    name = os.path.basename(path) + '.mcap'
    with open(os.path.join(path, name), 'rb') as a, open(fresh / name, 'rb') as b:
        assert a.read() == b.read()


def test_a_worker_warms_up_before_its_first_projection_and_keeps_nothing_of_it(
        pool, make_scenario):
    from projection_server.workers.warm_up import warm_up_job

    pool.run(job(make_scenario, 5.0), timeout=60.0)
    (warmed,) = pool.warm_ups
    assert warmed['error'] is None and warmed['seconds'] > 0
    warm = warm_up_job()
    assert not pool.store.path(warm, warm.key(pool.settings)).exists()
    assert not [p for p in pool.bag_dir.iterdir() if p.name.startswith('.tmp-')]


def test_a_worker_that_cannot_warm_up_says_why_instead_of_failing(monkeypatch, make_scenario):
    from projection_server.workers import warm_up

    monkeypatch.setattr(warm_up, '_description', lambda: {
        'scenario': make_scenario(), 'program': 'no_such_program', 'params': {}})
    report = warm_up.warm_up(None, None)
    assert 'no_such_program' in report['error']


def test_engine_parameters_left_by_anything_before_do_not_reach_a_projection(
        make_scenario, pool, tmp_path):
    from projection_server.simulation.runner import Simulator
    from projection_server.workers.run import project, run_projection

    grasp = job(make_scenario, 7.0, -0.02)
    fresh = run_projection(grasp, pool.settings, tmp_path / 'fresh' / 'bag')
    simulator = Simulator()
    try:
        # These survive resetSimulation: each projection must set them itself.
        simulator.client.setPhysicsEngineParameter(
            fixedTimeStep=0.01, numSubSteps=3, numSolverIterations=7,
            contactBreakingThreshold=0.05)
        warm = project(simulator, grasp, pool.settings, tmp_path / 'warm' / 'bag')
    finally:
        simulator.close()
    assert (tmp_path / 'warm' / 'bag' / 'bag.mcap').read_bytes() == (
        tmp_path / 'fresh' / 'bag' / 'bag.mcap').read_bytes()
    assert {**warm['meta'], 'bag': ''} == {**fresh['meta'], 'bag': ''}
    assert [warm[k] for k in ('fluents', 'events')] == [fresh[k] for k in ('fluents', 'events')]


def test_a_queued_projection_of_a_cancelled_owner_fails_as_cancelled(pool, make_scenario):
    running = pool.submit(job(make_scenario, 2.0), timeout=60.0, owner='q/1')
    queued = pool.submit(job(make_scenario, 2.5), timeout=60.0, owner='q/1')
    shared = pool.submit(job(make_scenario, 2.6), timeout=60.0, owner='q/1')
    pool.submit(job(make_scenario, 2.6), timeout=60.0, owner='q/2')
    assert pool.cancel('q/1') == 2
    for future in (running, queued):
        with pytest.raises(ProjectionError) as info:
            future.result(timeout=60.0)
        assert info.value.kind == 'cancelled'
    assert os.path.isdir(shared.result(timeout=60.0).bag)   # q/2 still wants it
    assert os.path.isdir(pool.run(job(make_scenario, 2.0), timeout=60.0))


def test_dropping_an_owners_projections_spares_the_running_one(pool, make_scenario):
    running = pool.submit(job(make_scenario, 3.1), timeout=60.0, owner='q/3')
    deadline = time.monotonic() + 60.0
    while not running.running():
        assert time.monotonic() < deadline
        time.sleep(0.01)
    queued = pool.submit(job(make_scenario, 3.2), timeout=60.0, owner='q/3')
    assert pool.cancel('q/3', running=False) == 1
    with pytest.raises(ProjectionError) as info:
        queued.result(timeout=60.0)
    assert info.value.kind == 'cancelled'
    assert os.path.isdir(running.result(timeout=60.0).bag)   # finished, and kept


def test_a_query_that_queued_a_grid_does_not_make_the_next_one_wait_for_all_of_it(
        pool, make_scenario):
    grid = pool.submit_all([job(make_scenario, f) for f in (4.1, 4.2, 4.3, 4.4)], 60.0,
                           owner='q/grid')
    deadline = time.monotonic() + 60.0
    while not grid[0].running():
        assert time.monotonic() < deadline
        time.sleep(0.01)
    single = pool.submit(job(make_scenario, 4.5), 60.0, owner='q/single')
    single.result(timeout=120.0)
    # One worker: the single one came right after the grid's first, before its last ones.
    assert not grid[2].done() and not grid[3].done()
    for future in grid:
        assert os.path.isdir(future.result(timeout=120.0).bag)


def test_a_worker_is_replaced_after_its_share_of_projections(make_scenario, tmp_path):
    from projection_server.workers.local import WorkerPool

    with WorkerPool(tmp_path, workers=1, max_projections=2) as pool:
        pool.run(job(make_scenario, 1.0), timeout=60.0)
        first = pool.worker_pids
        pool.run(job(make_scenario, 1.5), timeout=60.0)
        deadline = time.monotonic() + 30.0
        while pool.worker_pids in (first, [None]):   # replaced at once, with no job waiting
            assert time.monotonic() < deadline
            time.sleep(0.05)
        second = pool.worker_pids
        assert os.path.isdir(pool.run(job(make_scenario, 2.0), timeout=60.0))
        assert pool.worker_pids == second


def _worker_processes() -> set[int]:
    """The projection workers of this process's pools: its forkserver's children."""
    def children(pid):
        out = set()
        for entry in os.listdir('/proc'):
            if entry.isdigit():
                try:
                    stat = open(f'/proc/{entry}/stat').read()
                except OSError:
                    continue
                if int(stat.rsplit(')', 1)[1].split()[1]) == pid:
                    out.add(int(entry))
        return out
    return {w for c in children(os.getpid())
            if b'forkserver' in open(f'/proc/{c}/cmdline', 'rb').read() for w in children(c)}


def test_a_workers_successor_starts_while_it_still_works(make_scenario, tmp_path):
    from projection_server.workers.local import WorkerPool

    others = _worker_processes()   # of the module's other pools
    with WorkerPool(tmp_path, workers=1, max_projections=3) as pool:
        pool.run(job(make_scenario, 1.1), timeout=60.0)
        first = pool.worker_pids[0]
        assert _worker_processes() - others == {first}
        pool.run(job(make_scenario, 1.2), timeout=60.0)   # one left: its successor starts
        deadline = time.monotonic() + 30.0
        while _worker_processes() - others == {first}:
            assert time.monotonic() < deadline, 'no successor started'
            time.sleep(0.05)
        successors = _worker_processes() - others - {first}
        assert len(successors) == 1 and pool.worker_pids == [first]
        pool.run(job(make_scenario, 1.3), timeout=60.0)   # its share: it is replaced
        deadline = time.monotonic() + 60.0
        while pool.worker_pids in ([first], [None]):
            assert time.monotonic() < deadline
            time.sleep(0.05)
        assert pool.worker_pids == list(successors)   # by the one started ahead
        assert os.path.isdir(pool.run(job(make_scenario, 1.4), timeout=60.0))


def test_retention_deletes_the_least_recently_used_bags(tmp_path):
    for i, name in enumerate(['old', 'mid', 'new']):
        (tmp_path / name).mkdir()
        (tmp_path / name / 'metadata.yaml').write_text('x' * 100)
        os.utime(tmp_path / name, ns=(i * 10**9, i * 10**9))
    (tmp_path / '.tmp-1-0').mkdir()
    Retention(max_bags=2, max_bytes=None).apply(tmp_path, keep=tmp_path / 'new')
    assert sorted(p.name for p in tmp_path.iterdir()) == ['.tmp-1-0', 'mid', 'new']
    Retention(max_bags=None, max_bytes=150).apply(tmp_path, keep=tmp_path / 'mid')
    assert sorted(p.name for p in tmp_path.iterdir()) == ['.tmp-1-0', 'mid']


def _publish(store, name, size=100):
    tmp = store.tmp_dir()
    (tmp / name).mkdir()
    (tmp / name / 'metadata.yaml').write_text('x' * size)
    store.publish(tmp / name)
    tmp.rmdir()


def test_the_bag_store_keeps_the_most_recently_used_bags_without_rescanning(
        tmp_path, monkeypatch):
    from projection_server.workers import bag_store

    store = bag_store.BagStore(tmp_path, Retention(max_bags=3, max_bytes=None))
    for name in ['a', 'b', 'c']:
        _publish(store, name)
    store.touch(tmp_path / 'a')   # used again: now the most recent
    monkeypatch.setattr(bag_store, 'scan', lambda _: pytest.fail('rescanned'))
    _publish(store, 'd')
    _publish(store, 'e')
    assert sorted(p.name for p in tmp_path.iterdir()) == ['a', 'd', 'e']


def test_the_bag_store_counts_bags_other_processes_made_at_its_next_scan(
        tmp_path, monkeypatch):
    from projection_server.workers import bag_store

    monkeypatch.setattr(bag_store, 'RESCAN_EVERY', 2)
    store = bag_store.BagStore(tmp_path, Retention(max_bags=None, max_bytes=350))
    _publish(store, 'a')   # the first: the directory is read
    _publish(store, 'b')
    for name in ['x', 'y']:   # written by another process sharing the directory
        (tmp_path / name).mkdir()
        (tmp_path / name / 'metadata.yaml').write_text('x' * 100)
        os.utime(tmp_path / name, ns=(0, 0))
    _publish(store, 'c')   # the second since that scan: read again, 500 bytes
    assert sorted(p.name for p in tmp_path.iterdir()) == ['a', 'b', 'c']


def test_private_temporary_directories_of_dead_processes_are_deleted(tmp_path, monkeypatch):
    import tempfile

    from projection_server.workers.bag_store import private_tmp_dir

    monkeypatch.setattr(tempfile, 'tempdir', str(tmp_path))
    gone = tmp_path / 'projection-test-999999999-x'   # no such process
    gone.mkdir()
    mine = private_tmp_dir('projection-test-')
    assert mine.parent == tmp_path and mine.name.startswith(f'projection-test-{os.getpid()}-')
    assert not gone.exists()
    again = private_tmp_dir('projection-test-')
    assert mine.exists() and again.exists()   # this process's own are kept
