"""Runs the plunit tests that sit beside each Prolog source (prolog/*.plt)."""

from __future__ import annotations

import glob
import os
import subprocess

import pytest

from projection_server.service.prolog_bridge import prolog_dir

PLT = sorted(glob.glob(os.path.join(prolog_dir(), '**', '*.plt'), recursive=True))


def test_there_are_plunit_files():
    assert PLT, f'no .plt files under {prolog_dir()}'


@pytest.mark.parametrize('plt', PLT, ids=[os.path.basename(p) for p in PLT])
def test_plunit(plt):
    source = plt[:-4] + '.pl'
    # Load only this file's tests, not those of the modules it uses.
    goal = "load_files(Plt, [if(not_loaded)]), run_tests"
    out = subprocess.run(
        ['swipl', '-q', '-g', f'Plt = {plt!r}, {goal}', '-t', 'halt', source],
        capture_output=True, text=True, timeout=300, cwd=os.path.dirname(source))
    assert out.returncode == 0, out.stdout + out.stderr
    assert 'Warning' not in out.stderr, out.stderr
