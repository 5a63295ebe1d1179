"""Request fields are checked before anything runs (QueryManager.check_request, no ROS)."""

from __future__ import annotations

import pytest

from projection_server.service.queries import (ALL, INCREMENTAL, nesting_depth, ONCE, QueryError,
                                       QueryManager, ServerLimits)


@pytest.fixture
def manager():
    return QueryManager(ServerLimits())


@pytest.mark.parametrize('fields', [
    dict(mode='twice'),
    dict(timeout=float('inf')), dict(timeout=float('nan')), dict(timeout=1e10),
    dict(timeout=-0.5), dict(timeout=True), dict(timeout='1'),
    dict(max_solutions=2 ** 32 - 1), dict(max_solutions=-1), dict(max_solutions=1.5),
    dict(query_id='x' * 257), dict(query_id='a\nb'), dict(query_id='a*'), dict(query_id=3),
    dict(text='X = "' + 'a' * 100_001 + '"'), dict(text=b'X = 1'),
    dict(text='X = ' + '[' * 10_001 + ']' * 10_001),
])
def test_out_of_range_fields_are_invalid_requests(manager, fields):
    request = dict(mode=ONCE, query_id='q', text='X = 1', timeout=0.0, max_solutions=0)
    request.update(fields)
    with pytest.raises(QueryError) as info:
        manager.check_request(**request)
    assert info.value.kind == 'invalid_request' and info.value.message


@pytest.mark.parametrize('mode', [ONCE, ALL, INCREMENTAL])
def test_fields_within_range_pass(manager, mode):
    manager.check_request(mode, 'client/1', 'X = "((("', 3600.0, 10_000)


def test_a_nul_character_is_a_syntax_error(manager):
    with pytest.raises(QueryError) as info:
        manager.check_request(ONCE, '', 'X = 1\0garbage', 0.0, 0)
    assert info.value.kind == 'syntax_error'


@pytest.mark.parametrize('text, depth', [
    ('f(g(x), [a, {b}])', 3), ("X = '((((', Y = \"[[\"", 0), ('X = 0\'(', 0),
    ('X = 1 % (((\n', 0), ('/* [[[ */ f(a)', 1), ('f(' * 50 + ')' * 50, 50)])
def test_nesting_depth_skips_quotes_and_comments(text, depth):
    assert nesting_depth(text, 100) == depth
