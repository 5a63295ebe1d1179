"""The node with ``projection_backend:=ray`` on a real two-node Ray cluster of this machine.

A head and a worker node (``ray start --head``, ``ray start --address``) are started for
the module, the node joins them with ``ray_address`` and runs its two workers as Ray
actors, one per node. Table I through this node gives the timelines of the local backend
(the session's node); an actor killed mid-query fails that query with ``worker_crashed``
and the node serves on. Everything is stopped at the end; if Ray cannot start, the
fixture fails with Ray's output.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import signal
import time

from projection_interfaces.srv import PrologQuery
import pytest

from projection_server.client.discovery import handshake

from projection_server.reproduce import paper

Q = PrologQuery.Request
SIM_TIMEOUT = 120.0
TABLE_TIMEOUT = 900.0   # all 18 projections of an ALL_SOLUTIONS query, on a loaded machine
NAME = 'projection_server_ray'

TABLE_I = f'''
    make_projection(grasping, grasp_object,
                    [(F, force, {list(paper.GRASP_FORCES)}),
                     (P, position, {list(paper.GRASP_POSITIONS)})], TL),
    ( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip ; O = ok ),
    findall(E-T, occurs(E, T, TL), Es), findall(Fl-T, holds(Fl, T, TL), Fs),
    findall(Q-V, quantity(Q, V, TL), Qs)'''


@pytest.fixture(scope='module')
def cluster():
    """The cluster, and its settings in the environment of the processes that join it (a
    Ray instance started earlier in this process may have left others there)."""
    from projection_server.workers.ray.local_cluster import LocalCluster
    with LocalCluster(nodes=2, cpus_per_node=1) as running:
        saved = {key: os.environ.get(key) for key in running.env}
        os.environ.update(running.env)
        try:
            yield running
        finally:
            for key, value in saved.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value


@pytest.fixture(scope='module')
def ray_server(cluster, rclpy_context, tmp_path_factory):
    from projection_server.client.launcher import node_command, NodeProcess
    log = tmp_path_factory.mktemp('ray_node') / 'node.log'
    params = {'default_timeout': 5.0, 'max_engines': 4,
              'bag_dir': str(tmp_path_factory.mktemp('ray_bags')),
              'projection_backend': 'ray', 'ray_address': cluster.address,
              'projection_workers': 2}
    with NodeProcess(node_command(NAME, params), log) as proc:
        proc.wait_for_service(f'/{NAME}/query', timeout=180.0)
        yield f'/{NAME}'
    assert proc.returncode in (0, -signal.SIGINT), log.read_text()


@pytest.fixture(scope='module')
def ray_query(ray_server, node):
    import rclpy
    client = node.create_client(PrologQuery, f'{ray_server}/query')
    assert client.wait_for_service(timeout_sec=20.0) and handshake(node, ray_server, 20.0)

    def send(text, mode=Q.ALL_SOLUTIONS, timeout=SIM_TIMEOUT, query_id=''):
        return client.call_async(Q(mode=mode, id=query_id, query=text, timeout=timeout))

    def wait(future, timeout=TABLE_TIMEOUT + 60.0):
        rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
        assert future.done(), 'no answer from the ray node'
        return future.result()

    send.wait = wait
    yield send
    node.destroy_client(client)


def busy_actors(future, timeout=60.0):
    """Until an actor runs a projection (Ray titles its process by the task): their pids."""
    deadline = time.monotonic() + timeout
    while not (busy := [pid for pid, (_, cmd) in actor_processes().items()
                        if b'ProjectionActor.project' in cmd]):
        assert time.monotonic() < deadline and not future.done()
        time.sleep(0.005)
    return busy


def solutions(response):
    return [json.loads(s) for s in response.solutions]


def actor_processes():
    """Process ids of the machine's projection actors, with their parents (raylets)."""
    found = {}
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / 'cmdline').read_bytes()
            parent = int((entry / 'stat').read_text().rsplit(')', 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        if cmdline.startswith(b'ray::ProjectionActor'):
            found[int(entry.name)] = (parent, cmdline)
    return found


def test_the_workers_are_actors_on_both_nodes_of_the_cluster(ray_query):
    deadline = time.monotonic() + 300.0   # actors start beside the node, not before it
    while len(actors := actor_processes()) < 2 and time.monotonic() < deadline:
        time.sleep(0.2)
    assert len(actors) == 2
    raylets = {parent for parent, _ in actors.values()}
    assert len(raylets) == 2
    for raylet in raylets:
        assert b'raylet' in Path(f'/proc/{raylet}/cmdline').read_bytes()


def test_table_i_through_the_ray_backend_gives_the_local_backends_timelines(ray_query, call):
    r = ray_query.wait(ray_query(TABLE_I, timeout=TABLE_TIMEOUT))
    assert r.ok, r.message
    made = solutions(r)
    local = call(PrologQuery, 'query', Q(mode=Q.ALL_SOLUTIONS, query=TABLE_I,
                                         timeout=TABLE_TIMEOUT), timeout=TABLE_TIMEOUT + 60.0)
    assert local.ok, local.message
    assert len(made) == 18
    strip = ('TL',)   # the timeline handles are per node
    assert [{k: v for k, v in s.items() if k not in strip} for s in made] == \
        [{k: v for k, v in s.items() if k not in strip} for s in solutions(local)]
    outcomes = {(s['F'], s['P']): s['O'] for s in made}
    assert outcomes[(1, 0.0)] == 'slip' and outcomes[(11, 0.0)] == 'break'
    assert outcomes[(5, 0.0)] == 'ok'


SAMPLED = '''copy_scenario(grasping, S),
    scenario_set_property(S, egg1, friction, uniform(0.2, 0.4)),
    scenario_set_property(S, egg1, breaking_force, normal(10, 1.5)),
    outcome_probability(S, grasp_object, [(F, force, [2, 9])], [samples(6), seed(3)], TL,
                        ( \\+ occurs(break, _, TL), \\+ occurs(slip, _, TL) ), P),
    findall([Mu, B, O], ( make_projection(S, grasp_object, [(_, force, [F])],
                                     [samples(6), seed(3)], TL2),
                      quantity(sampled(egg1, friction), Mu, TL2),
                      quantity(sampled(egg1, breaking_force), B, TL2),
                      ( occurs(break, _, TL2) -> O = break ; occurs(slip, _, TL2) -> O = slip
                      ; O = ok ) ), Worlds)'''


def same_on_both_backends(ray_query, call, text):
    """The solutions of ``text`` on the ray node, asserted equal to the local node's but
    for the scenario and timeline handles, which are per node."""
    r = ray_query.wait(ray_query(text, timeout=TABLE_TIMEOUT))
    assert r.ok, r.message
    local = call(PrologQuery, 'query', Q(mode=Q.ALL_SOLUTIONS, query=text,
                                         timeout=TABLE_TIMEOUT), timeout=TABLE_TIMEOUT + 60.0)
    assert local.ok, local.message
    def answers(response):
        return [{k: v for k, v in s.items() if k not in ('TL', 'S')}
                for s in solutions(response)]

    made, here = answers(r), answers(local)
    # Both answers whole (pytest's diff of long dicts is cut at their first difference).
    assert made == here, f'ray: {json.dumps(made)}\nlocal: {json.dumps(here)}'
    return made


def test_worlds_drawn_from_a_belief_are_the_same_on_both_backends(ray_query, call):
    made = same_on_both_backends(ray_query, call, SAMPLED)
    assert len(made) == 2 and all(len(s['Worlds']) == 6 for s in made)
    # both forces met the same six eggs
    assert [w[0] for w in made[0]['Worlds']] == [w[0] for w in made[1]['Worlds']]


ROBUST = """copy_scenario(grasping, S),
    scenario_set_property(S, egg1, friction, uniform(0.15, 0.4)),
    scenario_set_property(S, egg1, breaking_force, normal(10, 1.5)),
    robust_parametrization(S, grasp_object, [(F, force, [1, 2, 5, 9])],
                           [seed(6), batch(4), certify(8)], TL,
                           ( \\+ occurs(break, _, TL), \\+ occurs(slip, _, TL) ), Best)"""


def test_a_robust_choice_is_the_same_on_both_backends(ray_query, call):
    made = same_on_both_backends(ray_query, call, ROBUST)
    assert made[0]['F'] == 5, made


def test_an_actor_killed_mid_query_fails_it_as_worker_crashed_and_the_node_serves_on(
        ray_query):
    # At 20x the steps: the grasp is still running when its actor is killed.
    text = ('simulate(grasping, grasp_object, [(_, force, [4.2]), (_, position, [0.01])], '
            '[physics(_{rate_hz: 4800}), timeout(120)], L)')
    future = ray_query(text, Q.ONCE, timeout=300.0)
    busy = busy_actors(future)
    os.kill(busy[0], signal.SIGKILL)
    r = ray_query.wait(future)
    assert not r.ok and r.error_kind == 'projection_error', r.message
    assert 'worker_crashed' in r.message
    r = ray_query.wait(ray_query(text, Q.ONCE, timeout=300.0))   # the restarted actor serves it
    assert r.ok, r.message
    assert Path(solutions(r)[0]['L']).is_dir()
    assert busy[0] not in actor_processes()


def test_finishing_a_projection_query_stops_its_running_ray_workers(
        ray_query, ray_server, node):
    import rclpy
    from projection_interfaces.srv import PrologFinish
    # Forces no other test projects: every one must be simulated; at 20x the steps, so that
    # the query is still running when it is finished (at the default step its six grasps
    # could all end before the finish request reached the node).
    text = ('make_projection(grasping, grasp_object, '
            '[(F, force, [2.31, 2.32, 2.33, 2.34, 2.35, 2.36])], '
            '[physics(_{rate_hz: 4800})], _), fail')
    future = ray_query(text, Q.ONCE, timeout=300.0, query_id='ray/cancel')
    busy = busy_actors(future)
    finish = node.create_client(PrologFinish, f'{ray_server}/finish')
    assert finish.wait_for_service(timeout_sec=20.0) and handshake(node, ray_server, 20.0)
    closed = ray_query.wait(finish.call_async(PrologFinish.Request(id='ray/cancel')))
    assert closed.closed == 1
    r = ray_query.wait(future)
    assert not r.ok and r.error_kind == 'cancelled', r.message
    deadline = time.monotonic() + 30.0   # the actor running its projection is killed
    while any(pid in actor_processes() for pid in busy):
        assert time.monotonic() < deadline, 'the running projection went on'
        time.sleep(0.05)
    r = ray_query.wait(ray_query('X = still_serving', Q.ONCE))
    assert solutions(r) == [{'X': 'still_serving'}]
    node.destroy_client(finish)
