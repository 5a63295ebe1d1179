"""The reproduction command: the paper's experiments through the real service, and a report."""

from __future__ import annotations

import dataclasses

import pytest

PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'


@pytest.fixture(scope='module')
def prolog(server):
    from projection_server.client import PrologClient
    client = PrologClient(server)
    assert client.wait_for_server(20.0)
    yield client
    client.close()


@pytest.fixture(scope='module')
def quick_table_i(prolog, tmp_path_factory):
    """The quick Table I run through the service: (printed lines, results, report path)."""
    from projection_server.reproduce import reproduce
    from projection_server.reproduce.experiments import TABLE_I_GRASPING
    lines: list[str] = []
    out = tmp_path_factory.mktemp('reproduction')
    results, report = reproduce(prolog, out, quick=True, experiments=[TABLE_I_GRASPING],
                                timeout=120.0, say=lines.append)
    return lines, results, report


def test_quick_table_i_shows_a_progress_line_per_projection(quick_table_i):
    lines, results, _ = quick_table_i
    progress = [line for line in lines if line.lstrip().startswith('[')]
    assert len(progress) == len(results[0].runs) == 6
    assert progress[0].strip().startswith('[1/6] force=1 position=0.0 -> ')
    assert all(' s total)' in line for line in progress)


def test_quick_table_i_is_printed_beside_the_paper_with_an_agreement_line(quick_table_i):
    text = '\n'.join(quick_table_i[0])
    lines = text.splitlines()
    assert 'TABLE I: grasping an egg  (paper/ours' in text
    header = next(line for line in lines if line.startswith('position'))
    assert header.split() == ['position', 'f1', 'f5', 'f11']
    row = next(line for line in lines if line.startswith('0.00 '))
    assert row.split()[1].startswith('slip/')      # the paper's f1 at 0.00
    agreement = next(line for line in lines if 'cells agree' in line)
    agree, total = agreement.split()[0].split('/')
    assert total == '6' and 0 <= int(agree) <= 6
    assert ('differs at' in agreement) == (agree != total)


def test_the_egg_slips_at_1_n_and_breaks_at_11_n(quick_table_i):
    _, results, _ = quick_table_i
    outcomes = {run.key: run.value for run in results[0].runs}
    assert outcomes[(1, 0.0)] == 'slip'
    assert outcomes[(11, 0.0)] == 'break'


def test_the_report_links_valid_png_files(quick_table_i):
    _, _, report = quick_table_i
    text = report.read_text()
    assert '## TABLE I: grasping an egg' in text
    images = [part.split(')')[0] for part in text.split('](')[1:]]
    assert 'table1_grid.png' in images
    assert any('frames' in name for name in images)
    for name in images:
        data = (report.parent / name).read_bytes()
        assert data.startswith(PNG_SIGNATURE), name
        assert len(data) > 1000, name


def test_an_experiment_whose_program_is_not_registered_is_skipped(prolog, tmp_path):
    from projection_server.reproduce import run_experiment
    from projection_server.reproduce.experiments import TABLE_II_POURING
    missing = dataclasses.replace(TABLE_II_POURING, program='no_such_program')
    lines: list[str] = []
    result = run_experiment(prolog, missing, quick=True, out=lines.append)
    assert result.skipped and not result.runs
    assert lines == [f'{missing.title}: skipped: program no_such_program is not registered '
                     'on the server (projection_program(no_such_program, _) fails)']


def test_the_paper_queries_are_the_papers(quick_table_i):
    from projection_server.reproduce.experiments import TABLE_I_GRASPING
    assert TABLE_I_GRASPING.query().startswith(
        'make_projection(grasping, grasp_object, [(P1, force, [1, 3, 5, 7, 9, 11]), '
        '(P2, position, [-0.02, 0.0, 0.02])], TL),\n'
        '( occurs(break,_,TL) -> O = break ; occurs(slip,_,TL) -> O = slip ; O = ok )')
