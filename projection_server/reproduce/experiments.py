"""The paper's experiments as small declarative objects, and running them through the service.

An :class:`Experiment` says which scenario and program to project over which parameter
grid, which Prolog goals classify or measure a solution's timeline ``TL``, and what the
paper reported. :func:`run_experiment` sends the paper's query as one INCREMENTAL query, so
that each projection is reported as its solution arrives.

    >>> result = run_experiment(client, TABLE_I_GRASPING, quick=True)
    >>> compare(result).summary()
    '6/6 cells agree'
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
import time
from typing import Any, Callable, TYPE_CHECKING

from projection_server.client.bindings import Compound
from projection_server.reproduce import paper

if TYPE_CHECKING:
    from collections.abc import Mapping, Sequence

    from projection_server.client import PrologClient

__all__ = [
    'EXPERIMENTS',
    'Comparison',
    'Event',
    'Experiment',
    'Measure',
    'Param',
    'Result',
    'Run',
    'Showcase',
    'TABLE_III_COOKED',
    'TABLE_III_POURED_PANCAKE',
    'TABLE_III_TURNING',
    'TABLE_II_POURING',
    'TABLE_I_GRASPING',
    'compare',
    'run_experiment',
]

UNDEFINED = 'none'   # the atom a measure goal binds when the timeline has no value


@dataclass(frozen=True)
class Param:
    """A formal parameter varied over ``values`` (``quick``: the reduced grid)."""

    var: str
    name: str
    values: tuple[float, ...]
    quick: tuple[float, ...]
    label: str = '{}'     # how a value is shown as a column or row heading

    def grid(self, quick: bool) -> tuple[float, ...]:
        return self.quick if quick else self.values

    def show(self, value: float) -> str:
        return self.label.format(value)


@dataclass(frozen=True)
class Measure:
    """A Prolog goal over the timeline ``TL`` that binds ``var``; ``column`` names it."""

    var: str
    goal: str
    column: str
    tolerance: Callable[[float], float] | None = None   # allowed |ours - paper| (numbers)


@dataclass(frozen=True)
class Showcase:
    """A run worth key frames: its parameters, a caption and the body to look at."""

    params: Mapping[str, float]
    caption: str
    target: str | None = None


@dataclass(frozen=True)
class Experiment:
    """One of the paper's tables as a projection query over a parameter grid."""

    key: str
    title: str
    scenario: str                      # a scenario's name, or the variable `setup` binds
    program: str
    params: tuple[Param, ...]
    measures: tuple[Measure, ...]
    paper: Mapping[tuple, Any]
    qualitative: bool = True
    sim_timeout: float | None = None   # None: make_projection/4's default
    rows: str | None = None            # qualitative layout: parameter per row ...
    cols: str | None = None            # ... and per column
    showcases: tuple[Showcase, ...] = ()
    setup: str | None = None           # goals run once before the projections

    def grid(self, quick: bool = False) -> list[tuple]:
        """The parameter combinations in the order make_projection enumerates them."""
        keys: list[tuple] = [()]
        for p in self.params:
            keys = [k + (v,) for k in keys for v in p.grid(quick)]
        return keys

    def query(self, quick: bool = False, physics: Mapping[str, float] | None = None) -> str:
        """The paper's query (make_projection + evaluation), plus what the report needs;
        ``physics``: the engine settings its projections run with instead of the program's
        (make_projection/5's physics option)."""
        choices = ', '.join(
            f'({p.var}, {p.name}, [{", ".join(_prolog_number(v) for v in p.grid(quick))}])'
            for p in self.params)
        if physics:
            chosen = ', '.join(f'{k}: {_prolog_number(v)}' for k, v in physics.items())
            options = [f'physics(_{{{chosen}}})']
            if self.sim_timeout is not None:
                options.insert(0, f'timeout({_prolog_number(self.sim_timeout)})')
            timeout = f'[{", ".join(options)}], '
        else:   # the paper's form; a number as the options is the timeout
            timeout = ('' if self.sim_timeout is None
                       else f'{_prolog_number(self.sim_timeout)}, ')
        goals = [self.setup] if self.setup else []
        goals += [f'make_projection({self.scenario}, {self.program}, [{choices}], {timeout}TL)']
        goals += [m.goal for m in self.measures]
        goals += ['timeline_property(TL, meta(Meta))', 'get_dict(bag, Meta, Bag)',
                  'get_dict(duration, Meta, Duration)',
                  'findall(E-T, occurs(E, T, TL), Events)']
        return ',\n'.join(goals)

    def registered_query(self) -> str:
        return f'projection_program({self.program}, _)'

    def key_of(self, solution: Mapping[str, Any]) -> tuple:
        """The grid key of a solution: its parameter bindings snapped to the grid values."""
        return tuple(_nearest(solution[p.var], p.values) for p in self.params)

    def value_of(self, solution: Mapping[str, Any]) -> Any:
        """An outcome (qualitative) or a dict column -> number or None (quantitative)."""
        values = {m.column: _plain(solution[m.var]) for m in self.measures}
        return values[self.measures[0].column] if self.qualitative else values

    def describe(self, key: tuple) -> str:
        return ' '.join(f'{p.name}={_prolog_number(v)}' for p, v in zip(self.params, key))


@dataclass(frozen=True)
class Event:
    """An event of a timeline: ``name`` the functor (``slip``), ``term`` the whole term."""

    name: str
    term: str
    start: float
    end: float


@dataclass
class Run:
    """One projection: its grid key, measured value, bag and timeline events."""

    key: tuple
    value: Any
    bag: str
    duration: float
    events: list[Event]
    elapsed: float


@dataclass
class Result:
    """The runs of one experiment, or why it was skipped or stopped."""

    experiment: Experiment
    quick: bool
    runs: list[Run] = field(default_factory=list)
    skipped: str | None = None
    error: str | None = None
    elapsed: float = 0.0
    physics: Mapping[str, float] | None = None   # chosen by the query; None: the program's

    def by_key(self) -> dict[tuple, Run]:
        return {r.key: r for r in self.runs}

    def find(self, params: Mapping[str, float]) -> Run | None:
        """The run whose parameters match ``params`` (names of the experiment's params)."""
        names = [p.name for p in self.experiment.params]
        for run in self.runs:
            values = dict(zip(names, run.key))
            if all(math.isclose(values[k], v, abs_tol=1e-9) for k, v in params.items()):
                return run
        return None


@dataclass
class Comparison:
    """Cell-by-cell agreement of a result with the paper."""

    agree: int
    total: int
    differences: list[tuple[tuple, str, Any, Any]]   # (key, column, paper, ours)
    experiment: Experiment

    def summary(self, limit: int = 6) -> str:
        text = f'{self.agree}/{self.total} cells agree'
        if not self.differences:
            return text
        shown = []
        for key, column, theirs, ours in self.differences[:limit]:
            where = self._where(key, column)
            shown.append(f'{where}: paper {_show(theirs)}, ours {_show(ours)}')
        more = len(self.differences) - len(shown)
        if not shown:
            return f'{text}; differs at {more} cell{"s" if more > 1 else ""}'
        return (f'{text}; differs at ' + '; '.join(shown)
                + (f'; and {more} more' if more > 0 else ''))

    def _where(self, key: tuple, column: str) -> str:
        exp = self.experiment
        if exp.qualitative and exp.rows and exp.cols:
            by = {p.name: (p, v) for p, v in zip(exp.params, key)}
            row, col = by[exp.rows], by[exp.cols]
            return f'({row[0].show(row[1])}, {col[0].show(col[1])})'
        cell = ', '.join(p.show(v) for p, v in zip(exp.params, key))
        return f'({cell})' + ('' if exp.qualitative else f' {column}')


def compare(result: Result) -> Comparison:
    """Compare each measured cell with the paper's; cells the paper lacks are not counted."""
    exp = result.experiment
    agree, total, diffs = 0, 0, []
    for run in result.runs:
        if run.key not in exp.paper:
            continue
        theirs = exp.paper[run.key]
        if exp.qualitative:
            cells = [(exp.measures[0], theirs, run.value)]
        else:
            cells = [(m, theirs.get(m.column), run.value.get(m.column)) for m in exp.measures]
        for measure, paper_value, ours in cells:
            total += 1
            if _cell_agrees(measure, paper_value, ours):
                agree += 1
            else:
                diffs.append((run.key, measure.column, paper_value, ours))
    return Comparison(agree, total, diffs, exp)


def run_experiment(client: PrologClient, experiment: Experiment, *, quick: bool = False,
                   timeout: float = 900.0, out: Callable[[str], None] = print,
                   physics: Mapping[str, float] | None = None) -> Result:
    """Run the experiment's query incrementally through ``client``; report each solution.

    ``physics`` chooses the engine settings of its projections (e.g. a finer reference).

    An experiment whose program is not registered on the server is skipped, and a query
    error stops the experiment with the runs made so far: neither raises.
    """
    from projection_server.client import PrologQueryError

    result = Result(experiment, quick, physics=dict(physics) if physics else None)
    if client.once(experiment.registered_query()) is None:
        result.skipped = (f'program {experiment.program} is not registered on the server '
                          f'({experiment.registered_query()} fails)')
        out(f'{experiment.title}: skipped: {result.skipped}')
        return result
    grid = experiment.grid(quick)
    out(f'{experiment.title}: {len(grid)} projections'
        + (' (quick grid)' if quick else '')
        + (f' with physics {_show(dict(physics))}' if physics else ''))
    start = last = time.monotonic()
    try:
        with client.query(experiment.query(quick, physics), timeout=timeout) as solutions:
            for i, solution in enumerate(solutions, 1):
                now = time.monotonic()
                run = Run(key=experiment.key_of(solution),
                          value=experiment.value_of(solution),
                          bag=str(solution['Bag']), duration=float(solution['Duration']),
                          events=_events(solution['Events']), elapsed=now - last)
                last = now
                result.runs.append(run)
                out(f'  [{i:{len(str(len(grid)))}}/{len(grid)}] '
                    f'{experiment.describe(run.key)} -> {_show(run.value)}  '
                    f'({run.elapsed:.1f} s, {now - start:.1f} s total)')
    except PrologQueryError as exc:
        result.error = f'{exc.kind}: {exc.message}'
        out(f'  stopped: {result.error}')
    result.elapsed = time.monotonic() - start
    return result


# -- the paper's three experiments ---------------------------------------------------------

def _quantity(term: str, var: str, column: str, tolerance) -> Measure:
    goal = f'( quantity({term}, {var}, TL) -> true ; {var} = {UNDEFINED} )'
    return Measure(var, goal, column, tolerance)


TABLE_I_GRASPING = Experiment(
    key='table1',
    title='TABLE I: grasping an egg',
    scenario='grasping',
    program='grasp_object',
    params=(Param('P1', 'force', paper.GRASP_FORCES, (1, 5, 11), 'f{}'),
            Param('P2', 'position', paper.GRASP_POSITIONS, (0.0, 0.02), '{:.2f}')),
    measures=(Measure('O', '( occurs(break,_,TL) -> O = break ; occurs(slip,_,TL) -> O = slip '
                           '; O = ok )', 'outcome'),),
    paper=paper.TABLE_I,
    rows='position', cols='force',
    showcases=(Showcase({'force': 1, 'position': 0.0}, 'force 1 N: the egg slips', 'egg1'),
               Showcase({'force': 11, 'position': 0.0}, 'force 11 N: the egg breaks',
                        'egg1')),
)

TABLE_II_POURING = Experiment(
    key='table2',
    title='TABLE II: pouring a pancake mix',
    scenario='pouring',
    program='pour',
    # The table's order: position slowest, then time, then angle.
    params=(Param('P1', 'position', paper.POUR_POSITIONS, (0.0,), '{:.2f}'),
            Param('P2', 'time', paper.POUR_TIMES, (0.5,), '{:.1f}'),
            Param('P3', 'angle', paper.POUR_ANGLES, (1.99, 2.14), '{:.2f}')),
    # Tolerances are ours (the paper gives no error bars): particle counts within a
    # quarter (at least 5 particles), offsets within 2 cm, roundness within 0.15.
    measures=(_quantity('particles_on(pancake_maker1)', 'Pan', 'pan',
                        lambda v: max(5.0, 0.25 * abs(v))),
              _quantity('particles_spilled(pancake_mix1)', 'Spill', 'spill',
                        lambda v: max(3.0, 0.5 * abs(v))),
              _quantity('centroid_offset_x(pancake_maker1)', 'OffX', 'off_x',
                        lambda v: 0.02),
              _quantity('centroid_offset_y(pancake_maker1)', 'OffY', 'off_y',
                        lambda v: 0.02),
              _quantity('roundness(pancake_maker1)', 'Round', 'round', lambda v: 0.15)),
    paper=paper.TABLE_II,
    qualitative=False,
    sim_timeout=600.0,
    showcases=(Showcase({'position': 0.0, 'time': 0.5, 'angle': 2.14},
                        'pouring: particles on the pan', 'pancake_maker1'),),
)

TABLE_III_TURNING = Experiment(
    key='table3',
    title='TABLE III: turning a pancake',
    scenario='turning',
    program='turn_pancake',
    params=(Param('P1', 'angle', paper.TURN_ANGLES, (0.3, 0.7), '{}'),),
    measures=(Measure('O', '( ( holds(upsidedown, _, TL) ; holds(upside_down(_), _, TL) ) '
                           '-> O = ok ; O = fail )', 'outcome'),),
    paper=paper.TABLE_III,
    sim_timeout=600.0,
    cols='angle',
    showcases=(Showcase({'angle': 0.3}, 'angle 0.3: the pancake mid-flip', 'pancake1'),),
)

# Table III again with the pancake the object model factory builds from the particles one
# pouring projection of Table II left on the pan (the paper's Fig. 7), in the turning
# scenario's kitchen with the same spatula.
POUR_ON_PAN = ('make_projection(pouring, pour, [(_, angle, [2.14]), (_, time, [0.5]), '
               '(_, position, [0.0])], 600.0, PourTL),\n')
TABLE_III_POURED_PANCAKE = Experiment(
    key='table3_poured',
    title='TABLE III with the poured pancake (Fig. 7)',
    scenario='S',
    program='turn_pancake',
    params=TABLE_III_TURNING.params,
    measures=TABLE_III_TURNING.measures,
    paper=paper.TABLE_III,
    sim_timeout=600.0,
    cols='angle',
    showcases=(Showcase({'angle': 0.1}, 'angle 0.1: the poured pancake mid-flip', 'pancake1'),),
    setup=(POUR_ON_PAN +
           'quantity(particles_on_positions(pancake_maker1), Points, PourTL),\n'
           'create_scenario(S),\n'
           'add_to_scenario(S, [kitchen_env, pr2_robot, pancake_maker1, spatula1,\n'
           '                    object(pancake, _{name: pancake1, particles: Points})])'),
)

# Table III with the pancake that emerges from the poured batter on the hot pan (issue 28):
# the batter one pour of Table II left on the pan (each of its particles: its position,
# temperature and bonds; not what stayed in the cup) cooks for COOK_TIME seconds on
# pancake_maker1 (195 degC) in a projection of its own (wait, with 20 solver iterations:
# a batter at rest on the pan, set alike at a 2x finer step), and what it became is
# handed on to the turning scenario's kitchen, pan and spatula. Cook once, turn six times.
COOK_TIME = 8.0   # s: the poured batter (about 160 particles) is set through at 8 s
COOKED_SETUP = (
    POUR_ON_PAN +
    'quantity(particles_on_positions(pancake_maker1), Poured, PourTL),\n'
    'quantity(particles_on_temperatures(pancake_maker1), PouredT, PourTL),\n'
    'quantity(particles_on_bonds(pancake_maker1), PouredBonds, PourTL),\n'
    'create_scenario(C),\n'
    'add_to_scenario(C, [kitchen_env, pancake_maker1, object(pancake_mix,\n'
    '    _{name: batter1, positions: Poured, temperatures: PouredT, bonds: PouredBonds})]),\n'
    f'make_projection(C, wait, [(_, duration, [{COOK_TIME!r}])],\n'
    '                [timeout(600.0), physics(_{solver_iterations: 20})], CookTL),\n'
    'quantity(particles_on_positions(pancake_maker1), Cooked, CookTL),\n'
    'quantity(particles_on_temperatures(pancake_maker1), CookedT, CookTL),\n'
    'quantity(particles_on_bonds(pancake_maker1), CookedBonds, CookTL),\n'
    'quantity(set_fraction(batter1), SetFraction, CookTL),\n'
    'create_scenario(S),\n'
    'add_to_scenario(S, [kitchen_env, pr2_robot, pancake_maker1, spatula1, object(pancake_mix,\n'
    '    _{name: batter1, positions: Cooked, temperatures: CookedT, bonds: CookedBonds})])')
TABLE_III_COOKED = replace(
    TABLE_III_POURED_PANCAKE,
    key='table3_cooked',
    title=f'TABLE III with the pancake cooked from the poured batter ({COOK_TIME:g} s)',
    showcases=(Showcase({'angle': 0.4}, 'angle 0.4: the cooked pancake mid-flip',
                        'pancake_maker1'),),
    setup=COOKED_SETUP,
)

EXPERIMENTS: tuple[Experiment, ...] = (TABLE_I_GRASPING, TABLE_II_POURING, TABLE_III_TURNING,
                                       TABLE_III_POURED_PANCAKE, TABLE_III_COOKED)


# -- helpers -------------------------------------------------------------------------------

def _prolog_number(value: float) -> str:
    # repr keeps the float's shortest exact text; Prolog reads it back unchanged.
    return repr(value)


def _nearest(value: Any, grid: Sequence[float]) -> float:
    best = min(grid, key=lambda g: abs(g - float(value)))
    return best if math.isclose(best, float(value), abs_tol=1e-9) else float(value)


def _plain(value: Any) -> Any:
    """Atoms as str (``none`` as None), numbers as numbers."""
    if isinstance(value, str):
        return None if value == UNDEFINED else str(value)
    return value


def _events(value: Any) -> list[Event]:
    events = []
    for pair in value or []:
        if not (isinstance(pair, Compound) and pair.name == '-' and len(pair.args) == 2):
            continue
        term, when = pair.args
        name = term.name if isinstance(term, Compound) else str(term)
        if isinstance(when, Compound) and when.name == 'interval':
            start, end = (float(a) for a in when.args)
        else:
            start = end = float(when)
        events.append(Event(name, _term_text(term), start, end))
    return sorted(events, key=lambda e: e.start)


def _term_text(term: Any) -> str:
    if isinstance(term, Compound):
        return f'{term.name}({", ".join(_term_text(a) for a in term.args)})'
    return str(term)


def _cell_agrees(measure: Measure, theirs: Any, ours: Any) -> bool:
    if theirs is None or ours is None:
        return theirs is None and ours is None
    if measure.tolerance is None or isinstance(theirs, str) or isinstance(ours, str):
        return theirs == ours
    return abs(float(ours) - float(theirs)) <= measure.tolerance(float(theirs)) + 1e-12


def _show(value: Any) -> str:
    if value is None:
        return '—'
    if isinstance(value, dict):
        return ' '.join(f'{k}={_show(v)}' for k, v in value.items())
    if isinstance(value, float):
        return f'{value:.3g}'
    return str(value)
