"""The query service as ROS 2 tools meet it: parameters set at run time, /rosout, fuzzing."""

from __future__ import annotations

import os
import time

from hypothesis import given, HealthCheck, settings, strategies as st
from projection_interfaces.srv import PrologQuery
import pytest

Q = PrologQuery.Request


def query(call, text, mode=Q.ONCE, **kw):
    return call(PrologQuery, 'query', Q(mode=mode, query=text, **kw))


def set_sandbox(call, value):
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    request = SetParameters.Request(parameters=[Parameter(
        name='sandbox', value=ParameterValue(type=ParameterType.PARAMETER_BOOL,
                                             bool_value=value))])
    assert call(SetParameters, 'set_parameters', request).results[0].successful


def test_sandbox_false_set_at_run_time_allows_unsafe_goals(call):
    r = query(call, "shell('true', S)")
    assert not r.ok and r.error_kind == 'permission_error'
    set_sandbox(call, False)
    try:
        r = query(call, "shell('true', S)")
        assert r.ok and r.solutions == ['{"S":0}']
    finally:
        set_sandbox(call, True)
    assert query(call, "shell('true', S)").error_kind == 'permission_error'


def test_query_errors_reach_rosout(call, node):
    import rclpy
    from rcl_interfaces.msg import Log
    seen = []
    sub = node.create_subscription(Log, '/rosout', seen.append, 100)
    try:
        deadline = time.monotonic() + 10
        while not any('rosout-probe' in m.msg for m in seen):
            assert time.monotonic() < deadline, [m.msg for m in seen]
            query(call, 'foo(', id='rosout-probe')
            rclpy.spin_once(node, timeout_sec=0.5)
        log = next(m for m in seen if 'rosout-probe' in m.msg)
        assert log.name == 'projection_server' and log.level == Log.INFO
        assert 'syntax_error' in log.msg
    finally:
        node.destroy_subscription(sub)


_ATOMS = st.sampled_from(['a', 'X', 'Y', '_', '[]', '"s"', '1', '-1.5e3', "'q a'", '0\'c'])
_OPS = st.sampled_from([', ', '; ', ' = ', ' is ', ' -> ', ' + ', ' =.. ', ':-', '\\+ '])
_PREDS = st.sampled_from(['member', 'length', 'atom_length', 'between', 'sleep', 'assertz',
                          'format', 'term_to_atom', 'findall', 'succ_or_fail', 'repeat'])


@st.composite
def prolog_text(draw, depth=0):
    """Grammar-shaped goals: calls, operators and lists, sometimes broken or deep."""
    kind = draw(st.integers(0, 5 if depth < 4 else 1))
    if kind <= 1:
        return draw(_ATOMS)
    if kind == 2:
        args = draw(st.lists(prolog_text(depth + 1), min_size=1, max_size=3))
        return f'{draw(_PREDS)}({", ".join(args)})'
    if kind == 3:
        return draw(prolog_text(depth + 1)) + draw(_OPS) + draw(prolog_text(depth + 1))
    if kind == 4:
        return '[' + ', '.join(draw(st.lists(prolog_text(depth + 1), max_size=3))) + ']'
    n = draw(st.integers(1, 20_000))
    return 'f(' * n + 'a' + ')' * draw(st.integers(0, n))


# CI runs a bounded number of examples; bench/fuzz.py runs more.
FUZZ_EXAMPLES = int(os.environ.get('PROJECTION_SERVER_FUZZ_EXAMPLES', '60'))


@settings(max_examples=FUZZ_EXAMPLES, deadline=None, derandomize=FUZZ_EXAMPLES <= 60,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(text=st.one_of(prolog_text(), st.text(max_size=200)),
       mode=st.sampled_from([Q.ONCE, Q.ALL_SOLUTIONS]),
       timeout=st.sampled_from([0.0, 0.5, 1.0, 1e10, -1.0, float('inf')]),
       max_solutions=st.sampled_from([0, 1, 5, 10_000, 2 ** 32 - 1]))
def test_fuzzed_requests_are_answered_within_their_limit(call, text, mode, timeout,
                                                         max_solutions):
    text = text.replace('\0', '')
    started = time.monotonic()
    r = call(PrologQuery, 'query', Q(mode=mode, query=text, timeout=timeout,
                                     max_solutions=max_solutions), timeout=30.0)
    took = time.monotonic() - started
    limit = timeout if 0 < timeout <= 3600 else 5.0  # the test node's default_timeout
    assert r.ok or r.error_kind, r
    # The margin is a loaded machine's (DDS, the node's threads), well below the call's
    # 30 s: a query that ignored its limit would not be answered in time.
    assert took < limit * (max_solutions if mode == Q.ALL_SOLUTIONS and timeout > 0 else 1) \
        + 15.0 or r.error_kind == 'timeout', (text[:80], took)
    assert query(call, 'X = 1').ok
