"""One reproduction: run experiments through a client, print the tables, write the report."""

from __future__ import annotations

from pathlib import Path
from typing import Callable, TYPE_CHECKING

from projection_server.reproduce.experiments import EXPERIMENTS, run_experiment
from projection_server.reproduce.fidelity import reference_physics
from projection_server.reproduce.report import format_table, write_report

if TYPE_CHECKING:
    from collections.abc import Sequence

    from projection_server.client import PrologClient
    from projection_server.reproduce.experiments import Experiment, Result

__all__ = ['reproduce']


def reproduce(client: PrologClient, out: str | Path, *, quick: bool = False,
              experiments: Sequence[Experiment] = EXPERIMENTS, timeout: float = 900.0,
              frames: bool = True, reference: bool = False,
              say: Callable[[str], None] = print) -> tuple[list[Result], Path]:
    """Run ``experiments`` through ``client``, print each table beside the paper's and
    write ``out/report.md``; return the results and the report's path.

    With ``reference``, each experiment runs again at a 4x finer time step with 4x the
    solver iterations, and its agreement with that run is shown beside the paper's."""
    results, references = [], {}
    for experiment in experiments:
        result = run_experiment(client, experiment, quick=quick, timeout=timeout, out=say)
        results.append(result)
        if reference and not result.skipped:
            references[experiment.key] = run_experiment(
                client, experiment, quick=quick, timeout=timeout, out=say,
                physics=reference_physics(client, experiment.program))
        if not result.skipped:
            say('')
            say(format_table(result, references.get(experiment.key)))
        say('')
    report = write_report(results, out, frames=frames, log=say, references=references)
    say(f'report: {report}')
    return results, report
