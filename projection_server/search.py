"""Optuna studies for ``best_parametrization/8`` (``prolog/search.pl``), by ask and tell.

Prolog owns the search loop: it asks a study for a batch of trials, projects them (the
batch on all workers at once), and tells each trial's outcome. This module owns the
studies, kept by an integer id::

    >>> study = create([['distance', 0.05, 0.3]], seed=0, budget=16)
    >>> trials = ask(study, 2)              # [{'trial': 0, 'params': {'distance': ...}}, ...]
    >>> tell(study, 0, 0.12, True)          # a feasible trial and its objective
    >>> tell(study, 1, 0.31, False)         # its constraint failed
    >>> release(study)

The sampler is Optuna's TPE (:class:`optuna.samplers.TPESampler`), seeded: the same seed
and the same outcomes give the same trials. A trial whose constraint fails is told with
the constraint ``feasible`` set to 1 (``Trial.set_constraint``): TPE ranks every infeasible
trial below the feasible ones, so it learns where the constraint fails instead of
forgetting the trial. A trial without an objective value is told as failed.

At most :data:`MAX_STUDIES` studies are kept; creating one more forgets the oldest.
Optuna's own logging and warnings are kept off the node's output.
"""

from __future__ import annotations

from collections import OrderedDict
import itertools
import logging
import threading
from typing import Any, TYPE_CHECKING
import warnings

if TYPE_CHECKING:
    import optuna

__all__ = [
    'MAX_STUDIES',
    'SearchError',
    'ask',
    'create',
    'release',
    'startup_trials',
    'studies',
    'tell',
    'trials',
]

MAX_STUDIES = 64
# The decimals of a suggested value: those of range/3's grid values (prolog/projection.pl).
DECIMALS = 9
CONSTRAINT = 'feasible'

_lock = threading.Lock()
_studies: OrderedDict[int, _Study] = OrderedDict()
_ids = itertools.count(1)
_quiet = False


class SearchError(Exception):
    """A study that does not exist (released, or forgotten after :data:`MAX_STUDIES`)."""


class _Study:
    def __init__(self, study: optuna.Study, space: dict[str, Any]) -> None:
        self.study = study
        self.space = space
        self.running: dict[int, optuna.Trial] = {}
        self.lock = threading.Lock()


def startup_trials(budget: int) -> int:
    """How many of ``budget`` trials TPE samples at random before it models: Optuna's 10,
    but at most half the budget, so that a small budget is not all random."""
    return max(1, min(10, budget // 2))


def create(space: list[list[Any]], seed: int, budget: int) -> int:
    """A new study that maximises over ``space``, ``[[name, low, high], ...]`` (floats
    between low and high), with a TPE sampler seeded with ``seed`` for a search of
    ``budget`` trials; its id."""
    optuna = _optuna()
    distributions = {str(name): optuna.distributions.FloatDistribution(float(low), float(high))
                     for name, low, high in space}
    sampler = optuna.samplers.TPESampler(seed=int(seed),
                                         n_startup_trials=startup_trials(int(budget)))
    study = _Study(optuna.create_study(direction='maximize', sampler=sampler), distributions)
    with _lock:
        key = next(_ids)
        _studies[key] = study
        while len(_studies) > MAX_STUDIES:
            _studies.popitem(last=False)
    return key


def ask(study: int, count: int) -> list[dict[str, Any]]:
    """``count`` new trials of ``study``, each ``{'trial': number, 'params': {name:
    value}}``. Trials asked before others are told count as running: TPE keeps the
    batch's trials apart (its constant liar)."""
    s = _get(study)
    with s.lock, warnings.catch_warnings():
        warnings.simplefilter('ignore')
        trials = []
        for _ in range(int(count)):
            trial = s.study.ask(s.space)
            s.running[trial.number] = trial
            trials.append({'trial': trial.number,
                           'params': {name: round(float(value), DECIMALS)
                                      for name, value in trial.params.items()}})
    return trials


def tell(study: int, trial: int, value: float | None, feasible: bool,
         constraint: float | None = None) -> None:
    """Tell ``study`` the outcome of its running ``trial``: the objective ``value`` (None:
    the trial had none: told as failed) and whether its constraint held, or by how much it
    missed: ``constraint`` (<= 0: held; a chance constraint's gap to its probability)."""
    optuna = _optuna()
    s = _get(study)
    with s.lock, warnings.catch_warnings():
        warnings.simplefilter('ignore')
        running = s.running.pop(int(trial), None)
        if running is None:
            raise SearchError(f'study {study} has no running trial {trial}')
        if value is None:
            s.study.tell(running, state=optuna.trial.TrialState.FAIL)
            return
        if constraint is None:
            constraint = 0.0 if feasible else 1.0
        running.set_constraint(CONSTRAINT, float(constraint))
        s.study.tell(running, float(value))


def trials(study: int) -> list[dict[str, Any]]:
    """What ``study`` was told: per trial its number, state (``COMPLETE``, ``FAIL`` or
    ``RUNNING``), value and feasibility (None until told)."""
    s = _get(study)
    key = f'constraints:{CONSTRAINT}'
    with s.lock:
        return [{'trial': t.number, 'state': t.state.name, 'value': t.value,
                 'feasible': (t.system_attrs[key] <= 0 if key in t.system_attrs else None)}
                for t in s.study.get_trials(deepcopy=False)]


def release(study: int) -> None:
    """Forget ``study`` (no error if it is gone)."""
    with _lock:
        _studies.pop(int(study), None)


def studies() -> int:
    """How many studies are kept."""
    with _lock:
        return len(_studies)


def _get(study: int) -> _Study:
    with _lock:
        s = _studies.get(int(study))
    if s is None:
        raise SearchError(f'no study {study}: it was released or forgotten '
                          f'(at most {MAX_STUDIES} are kept)')
    return s


def _optuna() -> Any:
    """Optuna, imported on first use (it takes a while) and silenced: its INFO line per
    trial and its experimental-feature warnings would flood the node's log."""
    global _quiet
    import optuna

    if not _quiet:
        optuna.logging.disable_default_handler()
        optuna.logging.enable_propagation()   # warnings go where the process logs
        optuna.logging.set_verbosity(logging.WARNING)
        _quiet = True
    return optuna
