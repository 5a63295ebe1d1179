"""One reproduction: run experiments through a client, print the tables, write the report."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
import threading
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
              frames: bool = True, reference: bool = False, concurrent: bool = True,
              say: Callable[[str], None] = print) -> tuple[list[Result], Path]:
    """Run ``experiments`` through ``client``, print each table beside the paper's and
    write ``out/report.md``; return the results and the report's path.

    With ``concurrent``, the experiments' queries are sent at once, so that the server's
    workers always have projections to run (one experiment's single cook or last pour
    would leave a core idle); what each prints is held until those before it have
    printed theirs. With ``reference``, each experiment runs again at a 4x finer time
    step with 4x the solver iterations, and its agreement with that run is shown beside
    the paper's."""
    lines = _InOrder(len(experiments), say)

    def run(k: int, experiment: Experiment) -> tuple[Result, Result | None]:
        tell = lines.channel(k)
        try:
            result = run_experiment(client, experiment, quick=quick, timeout=timeout,
                                    out=tell)
            finer = None
            if reference and not result.skipped:
                finer = run_experiment(client, experiment, quick=quick, timeout=timeout,
                                       out=tell,
                                       physics=reference_physics(client, experiment.program))
            if not result.skipped:
                tell('')
                tell(format_table(result, finer))
            tell('')
            return result, finer
        finally:
            lines.done(k)

    if concurrent and len(experiments) > 1:
        with ThreadPoolExecutor(len(experiments), thread_name_prefix='experiment') as pool:
            runs = [f.result() for f in [pool.submit(run, k, e)
                                         for k, e in enumerate(experiments)]]
    else:
        runs = [run(k, e) for k, e in enumerate(experiments)]
    results = [result for result, _ in runs]
    references = {result.experiment.key: finer for result, finer in runs if finer is not None}
    report = write_report(results, out, frames=frames, log=say, references=references)
    say(f'report: {report}')
    return results, report


class _InOrder:
    """The lines of ``n`` experiments run at once, said experiment by experiment: the
    first's as they come, a later one's held until those before it are done."""

    def __init__(self, n: int, say: Callable[[str], None]):
        self._say = say
        self._held: list[list[str]] = [[] for _ in range(n)]
        self._done = [False] * n
        self._current = 0
        self._lock = threading.Lock()

    def channel(self, k: int) -> Callable[[str], None]:
        def tell(line: str) -> None:
            with self._lock:
                if k == self._current:
                    self._say(line)
                else:
                    self._held[k].append(line)
        return tell

    def done(self, k: int) -> None:
        with self._lock:
            self._done[k] = True
            while self._current < len(self._done) and self._done[self._current]:
                self._current += 1
                if self._current < len(self._done):
                    for line in self._held[self._current]:
                        self._say(line)
                    self._held[self._current] = []
