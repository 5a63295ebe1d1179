"""Unit tests of the binding decoder and the table printer (pure functions)."""

from __future__ import annotations

from fractions import Fraction
import math

import pytest

from projection_server.client.bindings import (Atom, Compound, DecodeError, Var, decode,
                                        decode_solution, to_prolog_text)
from projection_server.client.cli import format_table


def test_atoms_and_strings_differ():
    assert type(decode('a')) is Atom and type(decode({'string': 'a'})) is str


def test_special_floats_and_rationals():
    assert decode({'float': 'inf'}) == math.inf and math.isnan(decode({'float': 'nan'}))
    assert decode({'rational': '1r3'}) == Fraction(1, 3)


def test_booleans_are_not_in_the_encoding():
    with pytest.raises(DecodeError):
        decode(True)


def test_prolog_text_round_trip_of_a_solution():
    s = decode_solution('{"X":{"functor":"f","args":["a",{"string":"s"},{"var":"_G1"},'
                        '[1,2.5],"hello world",{"functor":"[|]","args":["h",{"var":"T"}]}]}}')
    assert to_prolog_text(s['X']) == "f(a, \"s\", _G1, [1, 2.5], 'hello world', [h|T])"


def test_table_has_a_column_per_variable():
    table = format_table([{'X': Atom('a'), 'Y': Var('Y')}, {'X': 1, 'Y': Compound('g', ())}])
    assert table.splitlines() == ['X | Y', '--+----', 'a | Y', '1 | g()']


def test_table_of_no_solutions_and_of_a_ground_query():
    assert format_table([]) == 'false.'
    assert format_table([{}]) == 'true.'
