"""Reproduce the paper's experiments through the live service and write a report.

``python -m projection_server.reproduce [--out DIR] [--quick] [--server /projection_server]``
runs each of the paper's experiments (section IV, Tables I-III) as the paper's query through
:class:`~projection_server.client.PrologClient`, prints each table beside the paper's, and
writes ``DIR/report.md`` with coloured grids and key frames rendered from the bags.

Modules: :mod:`.paper` (the paper's tables as data), :mod:`.experiments` (the experiments
and running them), :mod:`.run` (a whole reproduction),
:mod:`.report` (text and Markdown tables, grids), :mod:`.explain` (why ours and
the paper's cells differ), :mod:`.render` (frames
from bags: :mod:`projection_server.render`, re-exported).
"""

from __future__ import annotations

from projection_server.reproduce.experiments import (
    compare, EXPERIMENTS, Experiment, Result, run_experiment)
from projection_server.reproduce.run import reproduce

__all__ = ['EXPERIMENTS', 'Experiment', 'Result', 'compare', 'reproduce', 'run_experiment']
