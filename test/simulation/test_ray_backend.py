"""The ray worker backend on a real local Ray instance: the bags and timelines of the local
backend, crashes, time limits, cancellation, of single projections and of trees of
projections that share their first steps; and that the local backend needs no Ray.

One Ray instance (started by the backend, as the node does with an empty ``ray_address``)
and one actor serve the whole module. If Ray cannot start, the fixture fails with Ray's
reason.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest
import yaml

from projection_server.simulation import Job, ProjectionError
from projection_server.workers import create_backend, WorkerBackend


def job(make_scenario, force, position=0.0):
    return Job.checked(make_scenario(), 'grasp_object', {'force': force, 'position': position})


@pytest.fixture(scope='module')
def ray_backend(tmp_path_factory):
    from projection_server.workers.ray import RayBackend
    with RayBackend(tmp_path_factory.mktemp('ray_bags'), workers=1) as backend:
        backend.placement()   # its actor is up: start-up is not what the tests time
        yield backend


def actor_pid(backend):
    (info,) = backend.placement()
    return info['pid']


def wait_until_projecting(pid, future, timeout=30.0):
    """Until the actor process ``pid`` runs a projection (Ray titles it by its task)."""
    deadline = time.monotonic() + timeout
    while b'ProjectionActor.project' not in Path(f'/proc/{pid}/cmdline').read_bytes():
        assert time.monotonic() < deadline and not future.done()
        time.sleep(0.005)


def test_the_ray_backend_is_a_worker_backend(ray_backend):
    assert isinstance(ray_backend, WorkerBackend)
    assert ray_backend.workers == 1


def test_a_ray_projection_gives_the_local_backends_bag_and_timeline(
        ray_backend, pool, make_scenario):
    made = ray_backend.submit(job(make_scenario, 9.0, 0.02), timeout=60.0).result(60.0)
    local = pool.submit(job(make_scenario, 9.0, 0.02), timeout=60.0).result(60.0)
    assert Path(made.bag).parent == ray_backend.bag_dir
    assert Path(made.bag).name == Path(local.bag).name   # one job key, one bag name
    files = sorted(p.name for p in Path(local.bag).iterdir())
    assert sorted(p.name for p in Path(made.bag).iterdir()) == files
    for name in files:
        assert (Path(made.bag) / name).read_bytes() == (Path(local.bag) / name).read_bytes()
    assert made.timeline['meta']['bag'] == made.bag
    assert {**made.timeline, 'meta': None} == {**local.timeline, 'meta': None}
    assert {**made.timeline['meta'], 'bag': ''} == {**local.timeline['meta'], 'bag': ''}
    assert ['break', ['egg1']] in [e[:2] for e in made.timeline['events']]


def test_a_mujoco_projection_on_ray_gives_the_local_backends_bag(
        ray_backend, pool, make_scenario):
    mujoco = Job.checked(make_scenario(), 'grasp_object', {'force': 9.0, 'position': 0.02},
                         {'engine': 'mujoco'})
    made = ray_backend.submit(mujoco, timeout=60.0).result(60.0)
    local = pool.submit(mujoco, timeout=60.0).result(60.0)
    assert Path(made.bag).name == Path(local.bag).name
    for name in sorted(p.name for p in Path(local.bag).iterdir()):
        assert (Path(made.bag) / name).read_bytes() == (Path(local.bag) / name).read_bytes()
    assert ['break', ['egg1']] in [e[:2] for e in made.timeline['events']]


def test_an_identical_projection_comes_from_the_bag_directory(ray_backend, make_scenario):
    first = ray_backend.submit(job(make_scenario, 5.0), timeout=60.0).result(60.0)
    again = ray_backend.submit(job(make_scenario, 5.0), timeout=60.0)
    assert again.done() and again.result().bag == first.bag


def test_an_actor_killed_mid_projection_fails_it_and_serves_the_next(
        ray_backend, make_scenario):
    pid = actor_pid(ray_backend)
    future = ray_backend.submit(job(make_scenario, 4.0), timeout=60.0)
    wait_until_projecting(pid, future)
    os.kill(pid, signal.SIGKILL)
    with pytest.raises(ProjectionError) as info:
        future.result(timeout=60.0)
    assert info.value.kind == 'worker_crashed'
    result = ray_backend.submit(job(make_scenario, 4.0), timeout=60.0).result(60.0)
    assert os.path.isdir(result.bag)
    assert actor_pid(ray_backend) != pid   # restarted by Ray
    assert not [p for p in ray_backend.bag_dir.iterdir() if p.name.startswith('.tmp-')]


def test_a_projection_over_its_time_limit_is_stopped(ray_backend, make_scenario):
    with pytest.raises(ProjectionError) as info:
        ray_backend.submit(job(make_scenario, 6.0), timeout=0.05).result(60.0)
    assert info.value.kind == 'timeout'
    assert os.path.isdir(ray_backend.run(job(make_scenario, 6.0), timeout=60.0))


def test_cancelling_an_owner_stops_its_running_and_queued_projections_only(
        ray_backend, make_scenario):
    pid = actor_pid(ray_backend)
    running = ray_backend.submit(job(make_scenario, 2.0), timeout=60.0, owner='q/1')
    queued = ray_backend.submit(job(make_scenario, 2.5), timeout=60.0, owner='q/1')
    shared = ray_backend.submit(job(make_scenario, 2.6), timeout=60.0, owner='q/1')
    ray_backend.submit(job(make_scenario, 2.6), timeout=60.0, owner='q/2')
    wait_until_projecting(pid, running)
    started = time.monotonic()
    assert ray_backend.cancel('q/1') == 2
    for future in (running, queued):
        with pytest.raises(ProjectionError) as info:
            future.result(timeout=60.0)
        assert info.value.kind == 'cancelled'
    assert time.monotonic() - started < 10.0
    assert os.path.isdir(shared.result(timeout=60.0).bag)   # q/2 still wants it
    assert actor_pid(ray_backend) != pid


def test_an_actor_is_replaced_by_a_fresh_one_after_max_projections(
        ray_backend, make_scenario):
    pid = actor_pid(ray_backend)
    ray_backend.max_projections = 1
    try:
        assert os.path.isdir(ray_backend.run(job(make_scenario, 3.5), timeout=60.0))
        assert actor_pid(ray_backend) != pid
    finally:
        ray_backend.max_projections = 200
    assert os.path.isdir(ray_backend.run(job(make_scenario, 3.75), timeout=60.0))


# Pours that share their first steps, with a small batter (forty particles).
SMALL = yaml.safe_load((Path(__file__).parent / 'pouring.yaml').read_text())
SMALL['entities'][1]['parts'][0]['properties']['particle_count'] = 40


def family(position, times=(0.2, 0.4)):
    return [Job.checked(SMALL, 'pour', {'angle': a, 'time': t, 'position': position})
            for t in times for a in (1.9, 2.1)]


LONGER = (0.2, 0.4, 0.6, 0.8)   # the holding times of a family of 8 pours


@pytest.fixture(scope='module')
def straight(pool):
    """The bags of three families made one by one by the local backend: files by bag name."""
    return {Path(r.bag).name: files(r.bag) for r in (
        pool.submit(job, timeout=60.0).result(60.0)
        for job in family(0.0) + family(0.02) + family(0.04, LONGER))}


def files(bag):
    return {f.name: f.read_bytes() for f in sorted(Path(bag).iterdir())}


def test_a_family_runs_as_one_tree_in_an_actor_with_the_local_backends_bags(
        ray_backend, straight, caplog):
    caplog.set_level(logging.DEBUG, logger='projection_server.workers.ray.backend')
    results = [f.result(timeout=120.0) for f in ray_backend.submit_all(family(0.0), 60.0)]
    assert 'a tree of 4 projections' in caplog.text
    for result in results:
        assert files(result.bag) == straight[Path(result.bag).name]


def test_a_tree_whose_actor_dies_runs_what_it_had_not_finished_one_by_one(
        ray_backend, straight):
    (info,) = ray_backend.placement()
    futures = ray_backend.submit_all(family(0.02), 60.0)
    futures[0].result(timeout=120.0)   # the tree is under way
    assert not futures[-1].done()
    os.kill(info['pid'], signal.SIGKILL)
    for result in [f.result(timeout=120.0) for f in futures]:
        assert files(result.bag) == straight[Path(result.bag).name]
    assert actor_pid(ray_backend) != info['pid']
    # The worker process (and so its tree) died with the actor.
    deadline = time.monotonic() + 10.0
    while os.path.exists(f'/proc/{info["worker_pid"]}'):
        assert time.monotonic() < deadline, 'the worker process outlived its actor'
        time.sleep(0.05)


def test_another_querys_projection_runs_while_the_tree_waits_and_changes_no_byte(
        ray_backend, straight, make_scenario):
    pid = actor_pid(ray_backend)
    futures = ray_backend.submit_all(family(0.04, LONGER), 60.0, owner='q/grid')
    deadline = time.monotonic() + 30.0
    while b'ProjectionActor.tree' not in Path(f'/proc/{pid}/cmdline').read_bytes():
        assert time.monotonic() < deadline and not futures[0].done()
        time.sleep(0.005)
    quick = ray_backend.submit(job(make_scenario, 5.5), 60.0, owner='q/quick')
    assert os.path.isdir(quick.result(timeout=60.0).bag)
    # One actor: the grasp did not wait for the whole tree.
    assert not all(f.done() for f in futures)
    for result in [f.result(timeout=120.0) for f in futures]:
        assert files(result.bag) == straight[Path(result.bag).name]
    assert actor_pid(ray_backend) == pid


def test_only_a_tree_with_projections_left_is_paused_for_another_querys(make_scenario):
    from concurrent.futures import Future

    from projection_server.workers.base import Worker, WorkerState
    from projection_server.workers.requests import Request

    def request(owner):
        return Request(job(make_scenario, 5.0), 'key', 60.0, Future(), {owner})

    worker = Worker(0, WorkerState.RUNNING_TREE,
                    leaves={0: request('q/grid'), 1: request('q/b')})
    assert worker.pausable_owners() == {'q/grid', 'q/b'}
    # Its projections have all ended and its end is on its way: nothing to pause for,
    # and a projection started now would keep the actor from the next family's tree.
    worker.leaves = {}
    assert worker.pausable_owners() is None
    worker.leaves = {1: request('q/b')}
    worker.state, worker.other = WorkerState.TREE_PAUSED, request('q/quick')
    assert worker.pausable_owners() is None   # it runs another query's projection already
    one = Worker(0, WorkerState.RUNNING, request=request('q'))
    assert one.pausable_owners() is None


def test_a_tree_over_its_time_limit_fails_each_projection_with_its_own_timeout(ray_backend):
    other = [Job.checked(SMALL, 'pour', {'angle': a, 'time': 0.3, 'position': 0.01})
             for a in (1.8, 2.0)]
    for future in ray_backend.submit_all(other, 0.05):
        with pytest.raises(ProjectionError) as info:
            future.result(timeout=120.0)
        assert info.value.kind == 'timeout'


def test_cancelling_a_trees_owner_stops_it(ray_backend):
    pid = actor_pid(ray_backend)
    other = [Job.checked(SMALL, 'pour', {'angle': a, 'time': 0.3, 'position': -0.01})
             for a in (1.8, 2.0, 2.2)]
    futures = ray_backend.submit_all(other, 60.0, owner='q/tree')
    deadline = time.monotonic() + 30.0
    while b'ProjectionActor.tree' not in Path(f'/proc/{pid}/cmdline').read_bytes():
        assert time.monotonic() < deadline and not futures[0].done()
        time.sleep(0.005)
    assert ray_backend.cancel('q/tree') == 3
    for future in futures:
        with pytest.raises(ProjectionError) as info:
            future.result(timeout=60.0)
        assert info.value.kind == 'cancelled'
    assert actor_pid(ray_backend) != pid


def test_an_actor_whose_worker_process_cannot_start_says_why(monkeypatch):
    from projection_server.simulation import load_settings
    from projection_server.workers.ray.actor import ProjectionActor

    monkeypatch.setattr(sys, 'executable', '/bin/false')   # the actor's class, without Ray
    error, ok = ProjectionActor(load_settings().to_dict()).ready()
    assert not ok and error.kind == 'simulation_failed'
    assert 'worker start-up: the worker process exited with code 1' in error.message


def test_an_unknown_backend_is_an_invalid_setting(tmp_path):
    with pytest.raises(ProjectionError) as info:
        create_backend('spark', tmp_path, 1)
    assert info.value.kind == 'invalid_settings' and 'ray' in info.value.message


def test_the_local_backend_runs_without_importing_ray(tmp_path):
    code = ('import sys\n'
            'from projection_server import projection\n'
            'from projection_server.workers import create_backend\n'
            f'create_backend("local", {str(tmp_path)!r}, 1).close()\n'
            'assert "ray" not in sys.modules, "ray was imported"\n')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120, check=False)
    assert done.returncode == 0, done.stderr
