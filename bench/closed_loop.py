"""The paper's promise on paired worlds: does projecting first reduce the undesired outcomes?

    tools/with_env.sh python bench/closed_loop.py                 # grasp, push and lift
    tools/with_env.sh python bench/closed_loop.py --only grasp --eggs 50 --truth wider,belief
    tools/with_env.sh python bench/closed_loop.py --only lift --truth wider,belief
    tools/with_env.sh python bench/closed_loop.py --only pour     # not in the default run

Kunze et al. (IROS 2011) say that projecting a plan before acting "reduces the number of
undesired outcomes". Here a robot acts on true objects whose properties are drawn from a
distribution (by default wider than its belief), and picks its action's parameters by one of
three policies:

(a) default: a fixed choice made without projecting (the program's defaults);
(b) nominal: the best choice in the one world of the belief's nominal values (a
    distribution's middle or mean: projections without samples);
(c) belief: the best choice over the belief's worlds, by the product's own decision
    predicates: robust_parametrization/7 over a grid, or best_parametrization/8 with
    samples(N) and chance(P) over a range.

A policy's choice depends on the belief only, so it is decided once and then executed on
every true object. Its time and projections are the medians of ``--repeat`` decisions, each
on a fresh copy of the scenario (the scenario's name is part of a projection's cache key, so
nothing is cached) with the seeds K, K+1, ... (``--seed`` K; (b) and (c) of a search share
each seed); the choice executed is the first's. A decision's projections are the bags it
added to the node's bag directory.

Execution stands in for the real world: object i is world i of the truth's seed
(``--truth-seed``), the same objects for every policy (paired), projected at 4x the
program's physics rate and 4x its solver iterations (projection_physics_setting/3's
defaults), so that the robot's model differs from the world both in the properties and in
the integration. ``--truth wider`` (the default) draws the objects from the task's truth,
``--truth belief`` from the belief itself; ``--truth wider,belief`` executes the same
decisions on both. Per policy the tables give:

* the undesired outcomes, with their Wilson 95 % interval (two-sided);
* the exact McNemar test of (c) against (b) and of (c) against (a): the two-sided binomial
  test (p = 1/2) on the discordant objects, those on which exactly one of the two failed;
  the counts of both kinds of discordant objects are printed with it;
* the utility of the choice: its mean over the true objects (per task below);
* the projections and seconds of a decision (medians over the repeats).

Grasp (``--eggs``, default 200): grasp_object(force, position) in scenario grasping. Belief:
egg1's friction uniform(0.2, 0.4), breaking_force normal(10, 1.5); truth: uniform(0.15,
0.45), normal(9, 2). Grid: forces 1-11 N every 1 N x positions -0.02, 0, 0.02 m. Undesired:
a slip or a break; utility 1 for an egg lifted whole, 0 otherwise.
  (a): the program's defaults, 5 N at 0 m.
  (b): of the cells ok (no slip, no break) in the nominal world, the one farthest, in grid
  steps (Euclidean), from any cell that is not ok; then the lower force, the position nearer
  the centre.
  (c): robust_parametrization/7 over the 33 cells (its defaults: samples(30), batch of twice
  the workers, confidence 0.95, risk 0.05, indifference 0.05, certify(59)), once under each
  rule among equals: prefer(margin) (its default), prefer(near([5, 0.0])) (keeps the
  default when it is among the equals) and prefer(-max_load(egg1)) (the gentlest grip).

Push (``--pushes``, default 100): the README's robust push. A PR2 closes its gripper, moves
to box1 (5 cm, 0.2 kg, at x 0.45 m on the table) and pushes it ``distance`` (range(0.05,
0.25) m) at 0.3 m/s, fast enough that the box slides on after the gripper stops, the farther
the lower its friction; too far and it slides off the table's edge. Belief: box1's friction
uniform(0.15, 0.6) (nominal 0.375); truth uniform(0.1, 0.7). Undesired: a fall
(occurs(drop(box1), _, TL)); utility: the box's displacement if it stays on the table, 0 if
it falls. The displacement pulls the nominal optimum to the edge of the fall: a cliff.
  (a): a fixed distance of 0.1 m (``--push-default``), a round figure chosen without
  projecting (in the nominal world the box stays on the table up to about 0.19 m).
  (b): best_parametrization/8 in the nominal world maximising displacement(box1) subject to
  \\+ occurs(drop(box1), _, TL), max_projections(``--push-nominal-budget``, 32).
  (c): the same with samples(``--push-samples``, 35) and chance(``--push-chance``, 0.9):
  35 worlds are the fewest that can prove 0.9 (Wilson, 95 %), so a feasible trial is one
  whose box stayed on the table in all 35; max_projections(``--push-budget``, 560: 16 N,
  twice best_parametrization/8's default, which left the search at the range's start with
  seed 1, bench/RESULTS.md 2026-11-28), certified on the fresh worlds that can prove the
  chance (29 for 0.9, one-sided Clopper-Pearson).

Lift (``--lifts``, default 100): "lift the egg as fast as it goes without losing it".
grasp_object(force ``--lift-force`` 3 N, position 0, lift_time) in scenario grasping, its
lift of 0.1 m (minimum jerk) taking lift_time in range(0.1, 1.0) s. Belief and truth as for
the grasp. Undesired: a slip or a break; utility: the lift's mean speed 0.1 m / lift_time
if the egg is lifted whole, 0 otherwise. Why a cliff: the pads hold the egg through the
lift iff 2 mu F >= m (g + 5.77 x 0.1 m / lift_time^2) (textbook, and the node at 240 and
960 Hz alike: test_physics_service), so the quicker the lift, the more friction it needs;
the nominal optimum is the quickest lift that holds an egg of the belief's middle friction
(0.3: about 0.17 s), at the edge of the slip of every egg with less.
  (a): the program's default, 1 s.
  (b): best_parametrization/8 in the nominal world maximising max_speed(egg1) (the egg's
  peak speed, 1.875 x 0.1 m / lift_time when held) subject to no slip and no break,
  max_projections(``--lift-nominal-budget``, 32).
  (c): the same with samples(``--lift-samples``, 73) and chance(``--lift-chance``, 0.95)
  (73 worlds are the fewest that can prove 0.95: a feasible trial held the egg in all 73),
  max_projections(``--lift-budget``, 1168: 16 trials), certified on 59 fresh worlds.

Pour (``--only pour``, ``--pours``, default 20; not in the default run: a fine pour takes
40-60 s of a worker, so 20 pours of three policies take about 25 min on 2 workers and a
decision of (c) over the belief about 10 more). pour(angle 2.14 rad, time, position) in
scenario pouring, the cup held off the pan's centre (``--pour-position``, -0.06 m, room for a
second pancake beside the first) for ``time`` in range(0.5, 2.0) s. Belief: pancake_mix1's
damping uniform(20, 40) /s; truth uniform(10, 50). Undesired: a spill (occurs(spill(_), _,
TL)); utility: the particles on the pancake maker if nothing spilled, 0 otherwise. Why a
cliff: the longer the hold, the more batter lands on the pan, the objective; but the more
batter, the farther it spreads, and off the centre it reaches the pan's edge, the sooner the
runnier the batter (bench/RESULTS.md, 2026-11-26: at -0.08 to -0.09 m a damping of 10 /s
spills where 50 /s does not). So the nominal optimum is the longest hold that does not spill
at damping 30, at the edge of the spill of a runnier batter. (a): time 0.5 s (the program's
default); (b), (c): as for the push, maximising particles_on(pancake_maker1) subject to
\\+ occurs(spill(_), _, TL), (b) with max_projections(16), (c) with
samples(``--pour-samples``, 16), chance(0.8) and max_projections(4 N). The cliff is this
design's argument, not yet a measurement: the pour has not been run on it.

With the defaults the grasp and the push take about 45 minutes on 2 cores shared with
another benchmark (load 5-7; the grasp's nine robust decisions are most of it, 1.5-2.5 min
each), less on a quiet machine; the lift about 6 minutes a decision seed, of which (c)'s
decision is 2.5-3 (bench/RESULTS.md, 2026-11-28).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import os
from pathlib import Path
import statistics
import sys
import tempfile
import time
from typing import Any, Callable

import harness

Z95 = 1.959963984540054
OK_GRASP = r'( \+ occurs(break, _, TL), \+ occurs(slip, _, TL) )'


def wilson(k: int, n: int) -> tuple[float, float]:
    """The Wilson score interval of k successes in n, 95 %, as wilson_interval/4."""
    p, z2 = k / n, Z95 * Z95
    denominator = 1 + z2 / n
    centre = (p + z2 / (2 * n)) / denominator
    half = Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


def mcnemar(only_x: int, only_y: int) -> float:
    """The exact McNemar test's two-sided p: the binomial test (p = 1/2) of ``only_x`` of the
    ``only_x + only_y`` discordant pairs; 1 without any."""
    n = only_x + only_y
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(only_x, only_y) + 1)) / 2 ** n
    return min(1.0, 2 * tail)


def say(text: str = '') -> None:
    print(text, flush=True)


def _product(lists: list[tuple[float, ...]]) -> list[list[float]]:
    out: list[list[float]] = [[]]
    for values in lists:
        out = [o + [v] for o in out for v in values]
    return out


# --- the node's answers -----------------------------------------------------------------
class Bench:
    """The client of the benchmark's node, and what its bag directory holds."""

    def __init__(self, client: Any, bag_dir: Path, timeout: float):
        self.client, self.bag_dir, self.timeout = client, bag_dir, timeout

    def all(self, query: str) -> list[dict[str, Any]]:
        return self.client.all(query, timeout=self.timeout, max_solutions=10_000)

    def one(self, query: str) -> dict[str, Any]:
        """The one solution of ``query``, its scenario S deleted."""
        solutions = self.all(query)
        if len(solutions) != 1:
            raise RuntimeError(f'{len(solutions)} solutions, not one: {query}')
        self.drop(solutions)
        return solutions[0]

    def drop(self, solutions: list[dict[str, Any]]) -> None:
        """Delete the scenario S the ``solutions`` were projected in."""
        if solutions:
            self.client.once(f'delete_scenario({solutions[0]["S"]})')

    def bags(self) -> int:
        """The bags in the bag directory (not the projections under way, .tmp-*)."""
        return sum(1 for e in os.scandir(self.bag_dir) if not e.name.startswith('.'))

    def defaults(self, program: str, names: tuple[str, ...]) -> tuple[float, ...]:
        found = {str(s['N']): float(s['V']) for s in self.all(
            f'projection_program({program}, Ps), member(D, Ps), '
            'get_dict(name, D, N), get_dict(default, D, V)')}
        return tuple(found[name] for name in names)


# --- tasks ------------------------------------------------------------------------------
Choice = tuple[float, ...]
Properties = tuple[tuple[str, str, str], ...]   # (entity, property, distribution)


@dataclass
class Decision:
    """A policy's choice (None: it found none) and what it said of it."""

    choice: Choice | None
    note: str = ''


@dataclass
class Policy:
    key: str       # 'a', 'b', 'c', 'c-margin', ...
    label: str
    decide: Callable[[Any, int], Decision] | None   # (bench, seed); None: fixed
    fixed: Choice | None = None


@dataclass
class Task:
    """A task: how to set a scenario up, decide, execute and score one object."""

    name: str
    names: tuple[str, ...]          # the chosen parameters, in a Choice's order
    belief: Properties
    truth: Properties
    set_up: Callable[[Properties], str]   # goals binding S to a fresh scenario
    program: Callable[[Choice | None], str]   # the program term (None: with variables)
    physics_program: str            # projection_physics_setting/3's program
    params: Callable[[Choice], str]       # make_projection's parameters of one choice
    measures: str                   # binds Undesired (0/1) and Utility (and extra) from TL
    extra: tuple[tuple[str, str], ...] = ()   # (variable, label) only printed
    settings: str = ''

    def shown(self, choice: Choice | None) -> str:
        if choice is None:
            return 'none'
        return ', '.join(f'{n} {v:.3g}' for n, v in zip(self.names, choice))


def properties_goals(properties: Properties) -> list[str]:
    return [f'scenario_set_property(S, {e}, {k}, {d})' for e, k, d in properties]


# Grasp ----------------------------------------------------------------------------------
FORCES = tuple(float(f) for f in range(1, 12))
POSITIONS = (-0.02, 0.0, 0.02)
GRASP_GRID = f'[(Force, force, {list(FORCES)}), (Position, position, {list(POSITIONS)})]'


EGG_BELIEF = (('egg1', 'friction', 'uniform(0.2, 0.4)'),
              ('egg1', 'breaking_force', 'normal(10, 1.5)'))
EGG_TRUTH = (('egg1', 'friction', 'uniform(0.15, 0.45)'),
             ('egg1', 'breaking_force', 'normal(9, 2)'))


def egg_set_up(props: Properties) -> str:
    return ', '.join(['copy_scenario(grasping, S)'] + properties_goals(props))


def grasp_task() -> Task:
    return Task(
        name='grasp', names=('force', 'position'),
        belief=EGG_BELIEF, truth=EGG_TRUTH, set_up=egg_set_up,
        program=lambda choice: 'grasp_object', physics_program='grasp_object',
        params=lambda c: f'[(Force, force, [{c[0]}]), (Position, position, [{c[1]}])]',
        measures=('( occurs(slip, _, TL) -> Slip = 1 ; Slip = 0 ), '
                  '( occurs(break, _, TL) -> Break = 1 ; Break = 0 ), '
                  'Undesired is max(Slip, Break), Utility is 1 - Undesired, '
                  'quantity(max_load(egg1), Load, TL)'),
        extra=(('Slip', 'slips'), ('Break', 'breaks'), ('Load', 'max load N')),
        settings=f'grid forces {list(FORCES)} N x positions {list(POSITIONS)} m')


def grasp_margin(cell: Choice, outside: list[Choice]) -> float:
    """Distance in grid steps from ``cell`` to the nearest of ``outside`` (inf: none)."""
    index = (FORCES.index(cell[0]), POSITIONS.index(cell[1]))
    return min((math.dist(index, (FORCES.index(o[0]), POSITIONS.index(o[1])))
                for o in outside), default=math.inf)


def grasp_nominal(task: Task) -> Callable[[Bench, int], Decision]:
    def decide(bench: Bench, seed: int) -> Decision:
        solutions = bench.all(
            f'{task.set_up(task.belief)}, make_projection(S, grasp_object, {GRASP_GRID}, '
            f'[timeout({bench.timeout:g})], TL), ( {OK_GRASP} -> Ok = 1 ; Ok = 0 )')
        bench.drop(solutions)
        cells = {(float(s['Force']), float(s['Position'])): int(s['Ok']) for s in solutions}
        ok = [c for c, v in cells.items() if v]
        if not ok:
            return Decision(None, 'no cell ok in the nominal world')
        outside = [c for c, v in cells.items() if not v]
        choice = min(ok, key=lambda c: (-grasp_margin(c, outside), c[0], abs(c[1])))
        return Decision(choice, f'{len(ok)} of {len(cells)} cells ok')
    return decide


def grasp_robust(task: Task, rule: str) -> Callable[[Bench, int], Decision]:
    def decide(bench: Bench, seed: int) -> Decision:
        s = bench.one(
            f'{task.set_up(task.belief)}, robust_parametrization(S, grasp_object, '
            f'{GRASP_GRID}, [seed({seed}), prefer({rule}), timeout({bench.timeout:g})], TL, '
            f'{OK_GRASP}, Best), get_dict(p, Best, P), get_dict(low, Best, Low), '
            'get_dict(n, Best, N), get_dict(certified, Best, Cert), '
            'get_dict(worlds, Best, W), get_dict(equals, Best, Eq), length(Eq, NEq)')
        return Decision((float(s['Force']), float(s['Position'])),
                        f'certified {s["Cert"]} p {float(s["P"]):.3f} low '
                        f'{float(s["Low"]):.3f} of {s["N"]}, {s["W"]} worlds, '
                        f'{s["NEq"]} equals')
    return decide


def grasp_policies(bench: Bench, task: Task) -> list[Policy]:
    default = bench.defaults('grasp_object', task.names)
    return [Policy('a', '(a) default', None, default),
            Policy('b', '(b) nominal grid', grasp_nominal(task)),
            Policy('c-margin', '(c) robust, margin', grasp_robust(task, 'margin')),
            Policy('c-near', '(c) robust, near([5, 0.0])',
                   grasp_robust(task, 'near([5, 0.0])')),
            Policy('c-gentle', '(c) robust, -max_load(egg1)',
                   grasp_robust(task, '-max_load(egg1)'))]


# Searches over a range: the push and the pour --------------------------------------------
def search_decide(task: Task, options: str, constraint: str, objective: str,
                  params: str, variable: str) -> Callable[[Bench, int], Decision]:
    """best_parametrization/8 over the belief's scenario, ``options`` with {seed}."""
    def decide(bench: Bench, seed: int) -> Decision:
        solutions = bench.all(
            f'{task.set_up(task.belief)}, best_parametrization(S, {task.program(None)}, '
            f'{params}, [{options.format(seed=seed)}, timeout({bench.timeout:g})], TL, '
            f'{constraint}, {objective}, Best), get_dict(value, Best, V), '
            'get_dict(projections, Best, Spent), '
            '( get_dict(low, Best, Low) -> true ; Low = none ), '
            '( get_dict(p, Best, P) -> true ; P = none ), '
            '( get_dict(n, Best, N) -> true ; N = none ), '
            '( get_dict(certified, Best, Cert) -> true ; Cert = none )')
        bench.drop(solutions)
        if not solutions:
            return Decision(None, 'no feasible trial')
        s = solutions[0]
        note = f'value {float(s["V"]):.4g}, {s["Spent"]} projections'
        if s['Cert'] != 'none':
            note += (f', certified {s["Cert"]} p {float(s["P"]):.3f} low '
                     f'{float(s["Low"]):.3f} of {s["N"]}')
        return Decision((float(s[variable]),), note)
    return decide


BOX = ('entity(box1, rigid_object, _{{shape: box, size_x: 0.05, size_y: 0.05, size_z: 0.05, '
       'mass: 0.2, friction: {friction}, pose: _{{xyz: [0.45, 0.0, 0.745]}}}})')


def push_plan(choice: Choice | None) -> str:
    return ('plan([close_gripper(10), move_to(box1, [-0.09, 0, 0], [orientation(side(0)), '
            'speed(1.0)]), move_by([D, 0, 0], [speed(0.3)]), move_by([-0.1, 0, 0])])')


def push_set_up(props: Properties) -> str:
    (friction,) = [d for e, k, d in props if (e, k) == ('box1', 'friction')]
    return ('create_scenario(S), add_to_scenario(S, [kitchen_env, pr2_robot, '
            + BOX.format(friction=friction) + '])')


PUSH_CONSTRAINT = r'\+ occurs(drop(box1), _, TL)'


def push_task() -> Task:
    return Task(
        name='push', names=('distance',),
        belief=(('box1', 'friction', 'uniform(0.15, 0.6)'),),
        truth=(('box1', 'friction', 'uniform(0.1, 0.7)'),),
        set_up=push_set_up, program=push_plan, physics_program='plan',
        params=lambda c: f'[(D, distance, [{c[0]!r}])]',
        measures=('( occurs(drop(box1), _, TL) -> Undesired = 1 ; Undesired = 0 ), '
                  'quantity(displacement(box1), Moved, TL), '
                  'Utility is (1 - Undesired) * Moved'),
        extra=(('Moved', 'displacement m'),),
        settings='push 0.3 m/s, distance in range(0.05, 0.25) m')


def push_policies(task: Task, args: Any) -> list[Policy]:
    searched = '[(D, distance, range(0.05, 0.25))]'
    nominal = search_decide(task, f'max_projections({args.push_nominal_budget}), seed({{seed}})',
                            PUSH_CONSTRAINT, 'displacement(box1)', searched, 'D')
    budget = (f'max_projections({args.push_budget}), ' if args.push_budget else '')
    belief = search_decide(task, f'samples({args.push_samples}), chance({args.push_chance}), '
                           + budget + 'seed({seed})', PUSH_CONSTRAINT, 'displacement(box1)',
                           searched, 'D')
    return [Policy('a', '(a) default', None, (args.push_default,)),
            Policy('b', '(b) nominal search', nominal),
            Policy('c', f'(c) samples({args.push_samples}) chance({args.push_chance})'
                   + (f' max {args.push_budget}' if args.push_budget else ''), belief)]


# Lift --------------------------------------------------------------------------------------
LIFT_OK = OK_GRASP


def lift_task(force: float) -> Task:
    return Task(
        name='lift', names=('lift_time',),
        belief=EGG_BELIEF, truth=EGG_TRUTH, set_up=egg_set_up,
        program=lambda choice: 'grasp_object', physics_program='grasp_object',
        params=lambda c: (f'[(Force, force, [{force!r}]), (Position, position, [0.0]), '
                          f'(Lift, lift_time, [{c[0]!r}])]'),
        measures=('( occurs(slip, _, TL) -> Slip = 1 ; Slip = 0 ), '
                  '( occurs(break, _, TL) -> Break = 1 ; Break = 0 ), '
                  'Undesired is max(Slip, Break), Utility is (1 - Undesired) * 0.1 / Lift, '
                  'quantity(max_speed(egg1), Speed, TL)'),
        extra=(('Slip', 'slips'), ('Break', 'breaks'), ('Speed', 'peak speed m/s')),
        settings=f'grasp at {force:g} N at the centre, lift 0.1 m in lift_time in '
                 'range(0.1, 1.0) s')


def lift_policies(task: Task, args: Any) -> list[Policy]:
    searched = (f'[(Force, force, [{args.lift_force!r}]), (Position, position, [0.0]), '
                '(Lift, lift_time, range(0.1, 1.0))]')
    nominal = search_decide(task, f'max_projections({args.lift_nominal_budget}), seed({{seed}})',
                            LIFT_OK, 'max_speed(egg1)', searched, 'Lift')
    belief = search_decide(task, f'samples({args.lift_samples}), chance({args.lift_chance}), '
                           f'max_projections({args.lift_budget}), seed({{seed}})',
                           LIFT_OK, 'max_speed(egg1)', searched, 'Lift')
    return [Policy('a', '(a) default', None, (1.0,)),
            Policy('b', '(b) nominal search', nominal),
            Policy('c', f'(c) samples({args.lift_samples}) chance({args.lift_chance}) '
                   f'max {args.lift_budget}', belief)]


def pour_task(position: float) -> Task:
    return Task(
        name='pour', names=('time',),
        belief=(('pancake_mix1', 'damping', 'uniform(20, 40)'),),
        truth=(('pancake_mix1', 'damping', 'uniform(10, 50)'),),
        set_up=lambda props: ', '.join(['copy_scenario(pouring, S)']
                                       + properties_goals(props)),
        program=lambda choice: 'pour', physics_program='pour',
        params=lambda c: (f'[(Angle, angle, [2.14]), (Time, time, [{c[0]!r}]), '
                          f'(Position, position, [{position!r}])]'),
        measures=('( occurs(spill(_), _, TL) -> Undesired = 1 ; Undesired = 0 ), '
                  'quantity(particles_on(pancake_maker1), On, TL), '
                  'quantity(particles_spilled(pancake_mix1), Spilled, TL), '
                  'Utility is (1 - Undesired) * On'),
        extra=(('On', 'particles on pan'), ('Spilled', 'spilled')),
        settings=f'pour at angle 2.14 rad, position {position} m, time in range(0.5, 2.0) s')


def pour_policies(task: Task, args: Any) -> list[Policy]:
    searched = (f'[(Angle, angle, [2.14]), (Time, time, range(0.5, 2.0)), '
                f'(Position, position, [{args.pour_position!r}])]')
    constraint, objective = r'\+ occurs(spill(_), _, TL)', 'particles_on(pancake_maker1)'
    nominal = search_decide(task, 'max_projections(16), seed({seed})', constraint, objective,
                            searched, 'Time')
    belief = search_decide(task, f'samples({args.pour_samples}), chance(0.8), '
                           f'max_projections({4 * args.pour_samples}), seed({{seed}})',
                           constraint, objective, searched, 'Time')
    return [Policy('a', '(a) default', None, (0.5,)),
            Policy('b', '(b) nominal search', nominal),
            Policy('c', f'(c) samples({args.pour_samples}) chance(0.8)', belief)]


# --- deciding, executing, reporting -----------------------------------------------------
@dataclass
class Timed:
    decisions: list[Decision]
    seconds: list[float]
    projections: list[int]


def decide_all(bench: Bench, task: Task, policies: list[Policy], seed: int, repeat: int
               ) -> dict[str, Timed]:
    timed: dict[str, Timed] = {}
    for policy in policies:
        if policy.decide is None:
            timed[policy.key] = Timed([Decision(policy.fixed, 'fixed')], [0.0], [0])
            continue
        t = timed[policy.key] = Timed([], [], [])
        for r in range(repeat):
            bags, start = bench.bags(), time.perf_counter()
            t.decisions.append(policy.decide(bench, seed + r))
            t.seconds.append(time.perf_counter() - start)
            t.projections.append(bench.bags() - bags)
        say(f'  {policy.label}: ' + '; '.join(
            f'seed {seed + r}: {task.shown(d.choice)} [{d.note}] ({s:.1f} s, {p} projections)'
            for r, (d, s, p) in enumerate(zip(t.decisions, t.seconds, t.projections))))
    return timed


def execute(bench: Bench, task: Task, choice: Choice, truth: Properties, objects: int,
            seed: int, physics: dict[str, int]) -> list[dict[str, float]]:
    """``choice`` done on each of ``objects`` true objects (worlds of ``seed`` of ``truth``)
    at ``physics``: per object its measures and its true properties (T0, T1, ...)."""
    dict_ = ', '.join(f'{k}: {v}' for k, v in physics.items())
    sampled = ', '.join(f'quantity(sampled({e}, {k}), T{i}, TL)'
                        for i, (e, k, _) in enumerate(truth))
    solutions = bench.all(
        f'{task.set_up(truth)}, make_projection(S, {task.program(choice)}, '
        f'{task.params(choice)}, [samples({objects}), seed({seed}), physics(_{{{dict_}}}), '
        f'timeout({bench.timeout:g})], TL), {sampled}, {task.measures}')
    bench.drop(solutions)
    if len(solutions) != objects:
        raise RuntimeError(f'{len(solutions)} of {objects} executions answered')
    names = ['Undesired', 'Utility'] + [v for v, _ in task.extra]
    return [{**{n: float(s[n]) for n in names},
             **{f'T{i}': float(s[f'T{i}']) for i in range(len(truth))}} for s in solutions]


def spread(values: list[float]) -> str:
    return f'{statistics.median(values):.3g} ({min(values):.3g}-{max(values):.3g})'


def report(task: Task, policies: list[Policy], timed: dict[str, Timed],
           runs: dict[str, list[dict[str, float]] | None]) -> None:
    say(f'  {"policy":32} {"choice":24} {"undesired":>9} {"95 % interval":>13} '
        f'{"utility":>8}' + ''.join(f' {label:>22}' for _, label in task.extra)
        + f' {"projections":>11} {"s/decision":>10}')
    for policy in policies:
        t, done = timed[policy.key], runs[policy.key]
        choice = t.decisions[0].choice
        if done is None:
            say(f'  {policy.label:32} {"none":24} (no choice: nothing executed)')
            continue
        bad = int(sum(o['Undesired'] for o in done))
        low, high = wilson(bad, len(done))
        say(f'  {policy.label:32} {task.shown(choice):24} {bad:>4}/{len(done):<4} '
            f'{100 * low:5.1f}-{100 * high:5.1f} % '
            f'{statistics.mean(o["Utility"] for o in done):>8.4g}'
            + ''.join(f' {spread([o[v] for o in done]):>22}' if v not in ('Slip', 'Break')
                      else f' {int(sum(o[v] for o in done)):>22}' for v, _ in task.extra)
            + f' {statistics.median(t.projections):>11g} {statistics.median(t.seconds):>10.2f}')
    for c in (p for p in policies if p.key.startswith('c')):
        for other in ('b', 'a'):
            x, y = runs.get(c.key), runs.get(other)
            if x is None or y is None:
                say(f'  McNemar {c.label} vs {other}: no pairs (a policy chose nothing)')
                continue
            only_c = sum(1 for p, q in zip(x, y) if p['Undesired'] and not q['Undesired'])
            only_o = sum(1 for p, q in zip(x, y) if q['Undesired'] and not p['Undesired'])
            say(f'  McNemar {c.label} vs ({other}): undesired under (c) only {only_c}, under '
                f'({other}) only {only_o}; exact two-sided p = {mcnemar(only_c, only_o):.3g}')


def goal(task: Task, policies: list[Policy], runs: dict[str, list[dict[str, float]] | None]
         ) -> None:
    """The brief's bar: (c) at most half of (b)'s undesired outcomes with McNemar p < 0.05
    and at least 80 % of its utility; for the grasp, (c) no worse than (b)."""
    b = runs.get('b')
    for c in (p for p in policies if p.key.startswith('c')):
        x = runs.get(c.key)
        if x is None or b is None:
            say(f'  bar, {c.label}: not decidable (a policy chose nothing)')
            continue
        nc, nb = sum(o['Undesired'] for o in x), sum(o['Undesired'] for o in b)
        uc, ub = (statistics.mean(o['Utility'] for o in r) for r in (x, b))
        only_c = sum(1 for p, q in zip(x, b) if p['Undesired'] and not q['Undesired'])
        only_b = sum(1 for p, q in zip(x, b) if q['Undesired'] and not p['Undesired'])
        pv = mcnemar(only_c, only_b)
        if task.name == 'grasp':
            say(f'  bar, {c.label}: no worse than (b): {nc:g} <= {nb:g}: '
                f'{"met" if nc <= nb else "not met"}')
        else:
            met = nc <= nb / 2 and pv < 0.05 and uc >= 0.8 * ub
            say(f'  bar, {c.label}: {nc:g} <= {nb / 2:g}, McNemar p {pv:.3g} < 0.05, utility '
                f'{uc:.4g} >= 0.8 x {ub:.4g}: {"met" if met else "not met"}')


def run_task(bench: Bench, task: Task, policies: list[Policy], objects: int, seed: int,
             truth_seed: int, repeat: int, truths: list[str]) -> None:
    """Decide by each policy, execute each choice on the true objects, print the tables."""
    from projection_server.reproduce.fidelity import reference_physics

    physics = reference_physics(bench.client, task.physics_program)   # 4x rate, iterations
    say()
    say(f'{task.name}: {task.settings}; {objects} true objects, executed at {physics}')
    say('  belief: ' + ', '.join(f'{e} {k} {d}' for e, k, d in task.belief))
    say('  truth:  ' + ', '.join(f'{e} {k} {d}' for e, k, d in task.truth)
        + f'; truth seed {truth_seed}; executed on: {", ".join(truths)}')
    say(f'  decision seeds {seed}..{seed + repeat - 1} ({repeat} timed decisions a policy, '
        'the first executed); ' + harness.machine())
    timed = decide_all(bench, task, policies, seed, repeat)
    for which in truths:
        truth = task.truth if which == 'wider' else task.belief
        say()
        say(f'  truth = {which}: ' + ', '.join(f'{e} {k} {d}' for e, k, d in truth)
            + f', {objects} objects of seed {truth_seed}')
        executed: dict[Choice, list[dict[str, float]]] = {}
        runs: dict[str, list[dict[str, float]] | None] = {}
        for policy in policies:
            choice = timed[policy.key].decisions[0].choice
            if choice is None:
                runs[policy.key] = None
                continue
            if choice not in executed:
                start = time.perf_counter()
                executed[choice] = execute(bench, task, choice, truth, objects, truth_seed,
                                           physics)
                say(f'  executing {task.shown(choice)} on {objects} objects: '
                    f'{time.perf_counter() - start:.1f} s; {harness.machine()}')
            runs[policy.key] = executed[choice]
        first = next(iter(executed.values()))
        for i, (entity, prop, _) in enumerate(truth):
            values = sorted(o[f'T{i}'] for o in first)
            say(f'  true {entity} {prop}: min {values[0]:.3g}, median '
                f'{statistics.median(values):.3g}, max {values[-1]:.3g}')
        report(task, policies, timed, runs)
        goal(task, policies, runs)


def main() -> int:
    parser = harness.arguments(__doc__, seed=1)
    parser.add_argument('--eggs', type=int, default=200, help='true eggs grasped (200)')
    parser.add_argument('--pushes', type=int, default=100, help='true boxes pushed (100)')
    parser.add_argument('--lifts', type=int, default=100, help='true eggs lifted (100)')
    parser.add_argument('--pours', type=int, default=20, help='true pours (20)')
    parser.add_argument('--repeat', type=int, default=3,
                        help='timed decisions of (b) and (c), grasp, push and lift (3)')
    parser.add_argument('--pour-repeat', type=int, default=1,
                        help='timed decisions of (b) and (c), pour (1)')
    parser.add_argument('--push-default', type=float, default=0.1,
                        help="(a)'s push distance, m (0.1)")
    parser.add_argument('--push-samples', type=int, default=35,
                        help="(c)'s worlds of the belief per push trial (35)")
    parser.add_argument('--push-chance', type=float, default=0.9,
                        help="(c)'s chance that the box stays on the table (0.9)")
    parser.add_argument('--push-budget', type=int, default=560,
                        help="(c)'s max_projections (560; 0: best_parametrization/8's "
                             'default, 8 x --push-samples)')
    parser.add_argument('--push-nominal-budget', type=int, default=32,
                        help="(b)'s max_projections (32)")
    parser.add_argument('--lift-force', type=float, default=3.0,
                        help="the lift's grip force, N (3)")
    parser.add_argument('--lift-samples', type=int, default=73,
                        help="(c)'s worlds of the belief per lift trial (73)")
    parser.add_argument('--lift-chance', type=float, default=0.95,
                        help="(c)'s chance that the egg is lifted whole (0.95)")
    parser.add_argument('--lift-budget', type=int, default=1168,
                        help="(c)'s max_projections (1168: 16 trials of 73 worlds)")
    parser.add_argument('--lift-nominal-budget', type=int, default=32,
                        help="(b)'s max_projections (32)")
    parser.add_argument('--pour-samples', type=int, default=16,
                        help="(c)'s worlds of the belief per pour trial (16)")
    parser.add_argument('--pour-position', type=float, default=-0.06,
                        help="the pour's offset from the pan's centre, m (-0.06)")
    parser.add_argument('--truth-seed', type=int, default=2026,
                        help='seed of the true objects (2026)')
    parser.add_argument('--truth', default='wider',
                        help='the true objects: wider (the task\'s truth), belief, or both '
                             'comma-separated (wider)')
    parser.add_argument('--only', choices=('grasp', 'push', 'lift', 'pour'),
                        help='one task (the pour runs only so)')
    parser.add_argument('--workers', type=int, default=2)
    args = parser.parse_args()
    truths = args.truth.split(',')
    if not set(truths) <= {'wider', 'belief'}:
        parser.error(f'--truth: wider, belief or both, not {args.truth}')
    harness.ros_domain(150)

    import rclpy

    say(f'closed_loop: policies (a) default, (b) nominal world, (c) belief, each executed on '
        f'the same true objects at 4x the rate and solver iterations; {args.workers} workers, '
        f'a fresh bag_dir; seed {args.seed}, truth seed {args.truth_seed}, truth '
        f'{args.truth}; {harness.machine()}')
    started = time.perf_counter()
    rclpy.init()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            bag_dir = Path(tmp) / 'bags'
            bag_dir.mkdir()
            params = {'bag_dir': str(bag_dir), 'projection_workers': args.workers,
                      'default_timeout': 7200.0, 'max_bags': 10_000_000}
            with harness.start_node(params, Path(tmp) / 'node.log', stop_timeout=20.0), \
                    harness.client() as client:
                bench = Bench(client, bag_dir, 3600.0)
                grasp, push, pour = grasp_task(), push_task(), pour_task(args.pour_position)
                lift = lift_task(args.lift_force)
                plan = [(grasp, lambda: grasp_policies(bench, grasp), args.eggs, args.repeat),
                        (push, lambda: push_policies(push, args), args.pushes, args.repeat),
                        (lift, lambda: lift_policies(lift, args), args.lifts, args.repeat),
                        (pour, lambda: pour_policies(pour, args), args.pours,
                         args.pour_repeat)]
                for task, policies, objects, repeat in plan:
                    if args.only == task.name or (args.only is None and task.name != 'pour'):
                        start = time.perf_counter()
                        run_task(bench, task, policies(), objects, args.seed, args.truth_seed,
                                 repeat, truths)
                        say(f'  {task.name}: {time.perf_counter() - start:.0f} s; '
                            f'{harness.machine()}')
    finally:
        rclpy.try_shutdown()
    say()
    say(f'closed_loop: {time.perf_counter() - started:.0f} s in all; {harness.machine()}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
