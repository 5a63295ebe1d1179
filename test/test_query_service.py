"""End to end: the real node over DDS, answering through its three services."""

from __future__ import annotations

import json
import subprocess
import threading
import time

from projection_interfaces.srv import PrologFinish, PrologNextSolution, PrologQuery
import pytest

from projection_server.client.bindings import Atom, Compound, Var
from projection_server.client import PrologQueryError

Q = PrologQuery.Request
N = PrologNextSolution.Response


def query(call, text, mode=Q.ONCE, **kw):
    return call(PrologQuery, 'query', Q(mode=mode, query=text, **kw))


def test_once_answers_in_the_response(call):
    r = query(call, 'member(X, [a, b])')
    assert r.ok and r.error_kind == ''
    assert r.solutions == ['{"X":"a"}']


def test_once_without_solution_is_ok_and_empty(call):
    r = query(call, 'member(X, [])')
    assert r.ok and r.solutions == []


def test_all_returns_the_four_lossless_solutions_of_the_readme_query(call):
    r = query(call, 'member(X, [a, f(Y), "s", 1.5])', mode=Q.ALL_SOLUTIONS)
    assert r.ok and not r.truncated
    assert [json.loads(s) for s in r.solutions] == [
        {'X': 'a', 'Y': {'var': 'Y'}},
        {'X': {'functor': 'f', 'args': [{'var': 'Y'}]}, 'Y': {'var': 'Y'}},
        {'X': {'string': 's'}, 'Y': {'var': 'Y'}},
        {'X': 1.5, 'Y': {'var': 'Y'}},
    ]


def test_all_stops_at_the_cap_and_says_so(call):
    r = query(call, 'between(1, inf, X)', mode=Q.ALL_SOLUTIONS, max_solutions=5)
    assert r.ok and r.truncated
    assert [json.loads(s)['X'] for s in r.solutions] == [1, 2, 3, 4, 5]


def test_all_uses_the_server_cap_by_default(call):
    r = query(call, 'between(1, inf, X)', mode=Q.ALL_SOLUTIONS)
    assert r.ok and r.truncated and len(r.solutions) == 50


def test_incremental_query_yields_solutions_one_by_one(call):
    r = query(call, 'member(X, [1, 2])', mode=Q.INCREMENTAL, id='inc-1')
    assert r.ok and r.id == 'inc-1' and r.solutions == []
    nxt = lambda: call(PrologNextSolution, 'next_solution',  # noqa: E731
                       PrologNextSolution.Request(id='inc-1'))
    assert (nxt().status, nxt().status) == (N.OK, N.OK)
    last = nxt()
    assert last.status == N.NO_SOLUTION
    assert nxt().status == N.WRONG_ID  # exhausted queries are released


def test_an_empty_id_gets_a_generated_one(call):
    a = query(call, 'true', mode=Q.INCREMENTAL)
    b = query(call, 'true', mode=Q.INCREMENTAL)
    assert a.id and b.id and a.id != b.id
    for r in (a, b):
        assert call(PrologFinish, 'finish', PrologFinish.Request(id=r.id)).closed == 1


def test_an_open_id_cannot_be_reused(call):
    assert query(call, 'true', mode=Q.INCREMENTAL, id='dup').ok
    r = query(call, 'true', mode=Q.INCREMENTAL, id='dup')
    assert not r.ok and r.error_kind == 'wrong_id'
    call(PrologFinish, 'finish', PrologFinish.Request(id='dup'))


def test_next_on_an_unknown_id_is_wrong_id(call):
    r = call(PrologNextSolution, 'next_solution', PrologNextSolution.Request(id='nope'))
    assert r.status == N.WRONG_ID and r.error_kind == 'wrong_id' and 'nope' in r.message


def test_finish_with_a_prefix_star_closes_only_that_clients_queries(call):
    for i in range(3):
        assert query(call, 'true', mode=Q.INCREMENTAL, id=f'alice/{i}').ok
    assert query(call, 'true', mode=Q.INCREMENTAL, id='bob/0').ok
    r = call(PrologFinish, 'finish', PrologFinish.Request(id='alice/*'))
    assert r.ok and r.closed == 3
    still = call(PrologNextSolution, 'next_solution', PrologNextSolution.Request(id='bob/0'))
    assert still.status == N.OK
    call(PrologFinish, 'finish', PrologFinish.Request(id='bob/0'))


@pytest.mark.parametrize('text, kind', [
    ('foo(', 'syntax_error'),
    ('', 'syntax_error'),
    ('no_such_predicate(1)', 'existence_error'),
    ('atom_length(f(x), L)', 'type_error'),
    ('length(L, -1)', 'domain_error'),
    ('X is Y + 1', 'instantiation_error'),
    ('X is 1 / 0', 'evaluation_error'),
    ("shell('touch /tmp/pwned')", 'permission_error'),
    ('halt', 'permission_error'),
    ('G = halt, call(G)', 'permission_error'),
    ('throw(my_ball)', 'exception'),
])
def test_errors_are_structured_and_the_node_keeps_serving(call, text, kind):
    r = query(call, text)
    assert not r.ok and r.error_kind == kind and r.message
    assert query(call, 'X = 1').solutions == ['{"X":1}']


def test_a_syntax_error_carries_its_position(call):
    r = query(call, 'foo(a b)')
    assert r.error_kind == 'syntax_error'
    error = json.loads(r.error)
    context = error['args'][1]
    assert context['functor'] == 'string' and context['args'][1] == 5


def test_an_endless_query_times_out(call):
    r = query(call, 'repeat, fail', timeout=0.5)
    assert not r.ok and r.error_kind == 'timeout'
    assert query(call, 'X = 1').ok


def test_a_query_that_swallows_its_time_limit_is_abandoned_and_aborted(call):
    from std_srvs.srv import Trigger
    swallow = 'repeat, catch((between(1, 100000, _), fail ; true), _, true), fail'
    r = query(call, swallow, timeout=0.5)
    assert not r.ok and r.error_kind == 'timeout' and 'abandoned' in r.message
    assert query(call, 'X = 1').ok
    deadline = time.monotonic() + 30   # a loaded machine's margin: never, if it leaked
    while json.loads(call(Trigger, 'ping', Trigger.Request()).message)['abandoned']:
        assert time.monotonic() < deadline, 'the abandoned engine was never released'
        time.sleep(0.2)


def test_an_error_in_incremental_mode_comes_with_next_solution(call):
    assert query(call, 'member(X, [1, 0]), Y is 1 / X', mode=Q.INCREMENTAL, id='e').ok
    nxt = lambda: call(PrologNextSolution, 'next_solution',  # noqa: E731
                       PrologNextSolution.Request(id='e'))
    assert nxt().status == N.OK
    failed = nxt()
    assert failed.status == N.QUERY_FAILED and failed.error_kind == 'evaluation_error'


def _set_idle_timeout(call, seconds):
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=seconds)
    r = call(SetParameters, 'set_parameters', SetParameters.Request(
        parameters=[Parameter(name='idle_timeout', value=value)]))
    assert r.results[0].successful


@pytest.fixture
def no_reaping(call):
    """The test node reaps a query idle for 5 s; on a loaded machine opening six can take
    longer, and the first would be reaped before the seventh is refused."""
    from rcl_interfaces.srv import GetParameters
    was = call(GetParameters, 'get_parameters',
               GetParameters.Request(names=['idle_timeout'])).values[0].double_value
    _set_idle_timeout(call, 120.0)
    yield
    _set_idle_timeout(call, was)


def test_too_many_live_queries_is_a_resource_error(call, no_reaping):
    ids = [f'cap/{i}' for i in range(6)]
    for i in ids:
        assert query(call, 'true', mode=Q.INCREMENTAL, id=i).ok
    r = query(call, 'X = 1')
    assert not r.ok and r.error_kind == 'resource_error' and 'max_engines' in r.message
    assert call(PrologFinish, 'finish', PrologFinish.Request(id='cap/*')).closed == 6
    assert query(call, 'X = 1').ok


def test_an_idle_incremental_query_is_closed(call):
    assert query(call, 'between(1, 3, X)', mode=Q.INCREMENTAL, id='idle').ok
    time.sleep(6.5)  # idle_timeout is 5 s in the test node, reaped every second
    r = call(PrologNextSolution, 'next_solution', PrologNextSolution.Request(id='idle'))
    assert r.status == N.WRONG_ID and 'idle' in r.message


def test_every_term_kind_decodes_losslessly(client):
    s = client.once('A = a, S = "s", I = 123456789012345678901234567890, F is 0.1 + 0.2, '
                    "L = [1, [2]], C = f(a, \"b\"), P = [a|T], D = t{k: 1}, Q = 'hello world', "
                    'E = [], N is nan, R is 1r3, U = V')
    assert s['A'] == Atom('a') and type(s['A']) is Atom
    assert s['S'] == 's' and type(s['S']) is str
    assert s['I'] == 123456789012345678901234567890
    assert s['F'] == 0.1 + 0.2
    assert s['L'] == [1, [2]]
    assert s['C'] == Compound('f', (Atom('a'), 'b'))
    assert s['P'] == Compound('[|]', (Atom('a'), Var('T'))) and s['T'] == Var('T')
    assert s['D'].tag == Atom('t') and s['D'].pairs == ((Atom('k'), 1),)
    assert s['Q'] == Atom('hello world')
    assert s['E'] == []
    assert s['N'] != s['N']  # nan
    assert str(s['R']) == '1/3'
    assert s['U'] == s['V'] == Var('U')


def test_the_client_iterator_finishes_on_exit(client, call):
    with client.query('between(1, inf, X)') as q:
        got = []
        for s in q:
            got.append(s['X'])
            if len(got) == 3:
                break
        qid = q.id
    assert got == [1, 2, 3]
    r = call(PrologNextSolution, 'next_solution', PrologNextSolution.Request(id=qid))
    assert r.status == N.WRONG_ID


def test_the_client_raises_query_errors(client):
    with pytest.raises(PrologQueryError) as info:
        client.once('atom_length(1, 2, 3)')
    assert info.value.kind == 'existence_error'


def test_concurrent_clients_interleave_incremental_queries(server, rclpy_context):
    """Four clients, each with its own node and incremental query, step in turn."""
    from projection_server.client import PrologClient
    clients = [PrologClient(server) for _ in range(4)]
    try:
        queries = [c.query(f'between({100 * i}, {100 * i + 19}, X)')
                   for i, c in enumerate(clients)]
        iters = [iter(q) for q in queries]
        seen = {i: [] for i in range(4)}
        barrier = threading.Barrier(4)

        def step(i):
            for _ in range(20):
                barrier.wait(timeout=30)
                seen[i].append(next(iters[i])['X'])
        threads = [threading.Thread(target=step, args=(i,)) for i in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=120)
        for i in range(4):
            assert seen[i] == list(range(100 * i, 100 * i + 20))
        for q in queries:
            q.close()
    finally:
        for c in clients:
            c.close()


def test_a_slow_query_does_not_block_others(call, server, rclpy_context):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    slow_node = rclpy.create_node('slow_client')
    executor = SingleThreadedExecutor()
    executor.add_node(slow_node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        slow = slow_node.create_client(PrologQuery, f'{server}/query')
        assert slow.wait_for_service(timeout_sec=10)
        future = slow.call_async(Q(mode=Q.ONCE, query='sleep(4), X = done'))
        time.sleep(0.5)
        assert query(call, 'X = 1').ok
        assert not future.done()  # answered while the slow query still runs
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        assert done.wait(15)
        assert future.result().solutions == ['{"X":"done"}']
    finally:
        executor.shutdown()
        spinner.join(5)
        slow_node.destroy_node()


def test_the_command_line_client_prints_a_table(server):
    out = subprocess.run(['prolog_query', 'member(X, [a, f(Y), "s", 1.5])'],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert lines[0].split() == ['X', '|', 'Y']
    assert [line.split('|')[0].strip() for line in lines[2:]] == ['a', 'f(Y)', '"s"', '1.5']


def test_the_command_line_client_reports_errors(server):
    out = subprocess.run(['prolog_query', 'foo('], capture_output=True, text=True, timeout=60)
    assert out.returncode == 1 and 'syntax_error' in out.stderr


def test_ping_reports_live_queries(call):
    from std_srvs.srv import Trigger
    r = call(Trigger, 'ping', Trigger.Request())
    assert r.success and 'engines' in json.loads(r.message)
