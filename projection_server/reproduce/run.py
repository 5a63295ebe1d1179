"""One reproduction: run experiments through a client, print the tables, write the report."""

from __future__ import annotations

from pathlib import Path
from typing import Callable, TYPE_CHECKING

from projection_server.reproduce.experiments import EXPERIMENTS, run_experiment
from projection_server.reproduce.report import format_table, write_report

if TYPE_CHECKING:
    from collections.abc import Sequence

    from projection_server.client import PrologClient
    from projection_server.reproduce.experiments import Experiment, Result

__all__ = ['reproduce']


def reproduce(client: PrologClient, out: str | Path, *, quick: bool = False,
              experiments: Sequence[Experiment] = EXPERIMENTS, timeout: float = 900.0,
              frames: bool = True,
              say: Callable[[str], None] = print) -> tuple[list[Result], Path]:
    """Run ``experiments`` through ``client``, print each table beside the paper's and
    write ``out/report.md``; return the results and the report's path."""
    results = []
    for experiment in experiments:
        result = run_experiment(client, experiment, quick=quick, timeout=timeout, out=say)
        results.append(result)
        if not result.skipped:
            say('')
            say(format_table(result))
        say('')
    report = write_report(results, out, frames=frames, log=say)
    say(f'report: {report}')
    return results, report
