"""The paper's promise, measured: does projecting first reduce the undesired outcomes?

    tools/with_env.sh python bench/closed_loop.py            # both tasks, about 26 min
    tools/with_env.sh python bench/closed_loop.py --only grasp --eggs 50 --samples 10

Kunze et al. (IROS 2011) say that projecting a plan before acting "reduces the number of
undesired outcomes". Here a robot acts on objects whose true properties are drawn from a
distribution wider than its belief, and picks its action's parameters by one of three
policies:

(a) default: the program's defaults, without projecting;
(b) nominal: the best cell of a grid of parametrizations in the one world of the belief's
    nominal values (a projection without samples);
(c) belief: the cell whose desired outcome is most probable over the belief
    (outcome_probability/7 with samples(N), seed(K)).

A policy's choice depends on the belief only, so it is decided once and then executed on
every object. Its time is the median of ``--repeat`` decisions, each on a fresh copy of the
scenario (the scenario's name is part of a projection's cache key, so nothing is cached),
(c)'s with the seeds K, K+1, ...; the choice executed is the first's. Its projections are the
bags the decision added to the node's bag directory.

Execution stands in for the real world: object i is world i of the truth's seed (the same
objects for every policy), projected at 4x the program's physics rate and 4x its solver
iterations (projection_physics_setting/3's defaults), so that the robot's model differs from
the world both in the properties and in the integration. Counts of undesired outcomes come
with their Wilson 95 % interval; as all policies act on the same objects, the objects on
which only one of two policies failed are printed too.

Grasp: grasp_object(force, position) in scenario grasping, ``--eggs`` eggs. Undesired: a
slip or a break. Belief: egg1's friction uniform(0.2, 0.4), breaking_force normal(10, 1.5);
truth: friction uniform(0.15, 0.45), breaking_force normal(9, 2). Grid: forces 1-11 N every
1 N x positions -0.02, 0, 0.02 m.
  (b): of the cells ok (no slip, no break) in the nominal world, the one farthest, in grid
  steps (Euclidean), from any cell that is not ok.
  (c): the highest lower bound of P(ok); among equals, the one farthest from the cells
  outside them, as (b).
  Then, for both, the lower force and the position nearer the centre.

Pour: pour(angle, time, position) in scenario pouring, ``--pours`` pours. Undesired: a spill
(spill(pancake_mix1): a particle of batter reaches the table). Belief: pancake_mix1's
damping (the batter's viscosity) uniform(20, 40) /s around the knowledge base's 30; truth
uniform(10, 50). Grid: angles 1.84, 1.99, 2.14 rad x holds 0.5, 1.0 s x positions -0.09,
0.0 m (the default 1.99, 0.5, 0.0 is one of them).
  (b): of the nominal world's pours without a spill, the one with most particles on the
  pancake maker.
  (c): the highest lower bound of P(no spill); among equals, the most particles on the pan,
  their mean over the same worlds (the decision's own projections, cached).
  Then, for both, farthest from the cells outside (as for the grasp), the smaller angle,
  the shorter hold, the position nearer the centre.
A pour costs about 10 s of a worker at its own physics and 40-60 s at the fine one, a grasp
0.1 s and 0.3-0.5 s: the pour has fewer objects, worlds and repeats by default. With the
defaults the whole run takes about 26 minutes on 2 cores (bench/RESULTS.md, 2026-11-26).

outcome_probability/7 runs with decide(T), T = max(0.9, halfway from the lower bound of N
successes in N to 1): a cell that succeeds in every world runs all N of them, one clearly
below T stops early.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import statistics
import sys
import tempfile
import time
from typing import Any

import harness

Z95 = 1.959963984540054


@dataclass(frozen=True)
class Task:
    """One task of the benchmark: its program, grid, belief, truth and what is undesired."""

    name: str
    scenario: str
    program: str
    grid: tuple[tuple[str, tuple[float, ...]], ...]   # (parameter, values), first slowest
    belief: tuple[tuple[str, str, str], ...]          # (entity, property, distribution)
    truth: tuple[tuple[str, str, str], ...]
    ok: str              # the desired outcome: a Prolog condition on the timeline TL
    measures: str        # binds each of `undesired` to 0/1 (and `amount`) from TL
    undesired: tuple[str, ...]   # the measures that are undesired outcomes
    amount: str | None = None    # a measure to maximise among equals (None: none)
    extra: tuple[str, ...] = ()  # measures only printed (median and range)
    origin: dict[str, float] = field(default_factory=dict)   # "gentler" is nearer this

    def params(self, cell: dict[str, float] | None = None) -> str:
        """make_projection's parameter list: the grid, or the one ``cell``."""
        return '[' + ', '.join(
            f'({var(name)}, {name}, {list(values) if cell is None else [cell[name]]})'
            for name, values in self.grid) + ']'

    def set_up(self, properties: tuple[tuple[str, str, str], ...]) -> str:
        """Goals making S a copy of the task's scenario with ``properties`` set."""
        return ', '.join([f'copy_scenario({self.scenario}, S)'] + [
            f'scenario_set_property(S, {entity}, {key}, {value})'
            for entity, key, value in properties])


GRASP = Task(
    name='grasp', scenario='grasping', program='grasp_object',
    grid=(('force', tuple(float(f) for f in range(1, 12))), ('position', (-0.02, 0.0, 0.02))),
    belief=(('egg1', 'friction', 'uniform(0.2, 0.4)'),
            ('egg1', 'breaking_force', 'normal(10, 1.5)')),
    truth=(('egg1', 'friction', 'uniform(0.15, 0.45)'),
           ('egg1', 'breaking_force', 'normal(9, 2)')),
    ok=r'( \+ occurs(break, _, TL), \+ occurs(slip, _, TL) )',
    measures=('( occurs(slip, _, TL) -> Slip = 1 ; Slip = 0 ), '
              '( occurs(break, _, TL) -> Break = 1 ; Break = 0 ), '
              'quantity(max_load(egg1), Load, TL)'),
    undesired=('Slip', 'Break'), extra=('Load',),
    origin={'force': 0.0, 'position': 0.0})

POUR = Task(
    name='pour', scenario='pouring', program='pour',
    grid=(('angle', (1.84, 1.99, 2.14)), ('time', (0.5, 1.0)), ('position', (-0.09, 0.0))),
    belief=(('pancake_mix1', 'damping', 'uniform(20, 40)'),),
    truth=(('pancake_mix1', 'damping', 'uniform(10, 50)'),),
    ok=r'\+ occurs(spill(_), _, TL)',
    measures=('( occurs(spill(_), _, TL) -> Spill = 1 ; Spill = 0 ), '
              'quantity(particles_on(pancake_maker1), On, TL), '
              'quantity(particles_spilled(pancake_mix1), Spilled, TL)'),
    undesired=('Spill',), amount='On', extra=('On', 'Spilled'),
    origin={'angle': 0.0, 'time': 0.0, 'position': 0.0})


def var(name: str) -> str:
    return name.capitalize()


def wilson(k: int, n: int) -> tuple[float, float]:
    """The Wilson score interval of k successes in n, 95 %, as wilson_interval/4."""
    p, z2 = k / n, Z95 * Z95
    denominator = 1 + z2 / n
    centre = (p + z2 / (2 * n)) / denominator
    half = Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


def decide_threshold(samples: int) -> float:
    return max(0.9, (wilson(samples, samples)[0] + 1) / 2)


# --- choosing among the cells of a grid -------------------------------------------------
def key(task: Task, cell: dict[str, Any]) -> tuple[float, ...]:
    return tuple(float(cell[name]) for name, _ in task.grid)


def margin(task: Task, cell: tuple[float, ...], outside: list[tuple[float, ...]]) -> float:
    """Distance in grid steps from ``cell`` to the nearest of ``outside`` (inf: none)."""
    index = [values.index(v) for (_, values), v in zip(task.grid, cell)]
    return min((math.dist(index, [values.index(v) for (_, values), v in zip(task.grid, o)])
                for o in outside), default=math.inf)


def gentleness(task: Task, cell: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(abs(v - task.origin[name]) for (name, _), v in zip(task.grid, cell))


def best(task: Task, candidates: list[tuple[float, ...]], cells: list[tuple[float, ...]],
         amount: dict[tuple[float, ...], float] | None = None) -> tuple[float, ...]:
    """Of ``candidates`` (a subset of the grid's ``cells``): the most ``amount``, then the
    farthest from the cells that are not candidates, then the gentlest."""
    outside = [c for c in cells if c not in candidates]
    return min(candidates, key=lambda c: (-(amount or {}).get(c, 0.0),
                                          -margin(task, c, outside), gentleness(task, c)))


def shown(task: Task, cell: tuple[float, ...]) -> str:
    return ', '.join(f'{name} {v:g}' for (name, _), v in zip(task.grid, cell))


# --- the node's answers -----------------------------------------------------------------
class Bench:
    """The client of the benchmark's node, and what its bag directory holds."""

    def __init__(self, client: Any, bag_dir: Path, timeout: float):
        self.client, self.bag_dir, self.timeout = client, bag_dir, timeout

    def all(self, query: str) -> list[dict[str, Any]]:
        return self.client.all(query, timeout=self.timeout, max_solutions=10_000)

    def drop(self, solutions: list[dict[str, Any]]) -> None:
        """Delete the scenario S the ``solutions`` were projected in."""
        if solutions:
            self.client.once(f'delete_scenario({solutions[0]["S"]})')

    def bags(self) -> int:
        """The bags in the bag directory (not the projections under way, .tmp-*)."""
        return sum(1 for e in os.scandir(self.bag_dir) if not e.name.startswith('.'))

    def defaults(self, task: Task) -> tuple[float, ...]:
        found = {str(s['N']): float(s['V']) for s in self.all(
            f'projection_program({task.program}, Ps), member(D, Ps), '
            'get_dict(name, D, N), get_dict(default, D, V)')}
        return tuple(found[name] for name, _ in task.grid)


def measured(task: Task, solution: dict[str, Any]) -> dict[str, float]:
    return {m: float(solution[m]) for m in task.undesired + task.extra}


def nominal(bench: Bench, task: Task) -> dict[tuple[float, ...], dict[str, float]]:
    """Each cell's measures in the belief's nominal world, on a fresh copy of the scenario."""
    solutions = bench.all(f'{task.set_up(task.belief)}, '
                          f'make_projection(S, {task.program}, {task.params()}, '
                          f'[timeout({bench.timeout:g})], TL), {task.measures}')
    bench.drop(solutions)
    return {key(task, {n: s[var(n)] for n, _ in task.grid}): measured(task, s)
            for s in solutions}


def choose_nominal(task: Task, outcomes: dict[tuple[float, ...], dict[str, float]]
                   ) -> tuple[float, ...] | None:
    ok = [c for c, m in outcomes.items() if not any(m[u] for u in task.undesired)]
    if not ok:
        return None
    amount = ({c: outcomes[c][task.amount] for c in ok} if task.amount else None)
    return best(task, ok, list(outcomes), amount)


def belief(bench: Bench, task: Task, samples: int, seed: int
           ) -> tuple[tuple[float, ...], dict[tuple[float, ...], dict[str, float]],
                      dict[tuple[float, ...], float]]:
    """(c)'s choice, each cell's P(ok) (p, low, high, n) and the tied cells' mean amount."""
    threshold = decide_threshold(samples)
    options = f'[samples({samples}), seed({seed}), decide({threshold:.4f}), ' \
              f'timeout({bench.timeout:g})]'
    solutions = bench.all(
        f'{task.set_up(task.belief)}, outcome_probability(S, {task.program}, {task.params()}, '
        f'{options}, TL, {task.ok}, P), get_dict(p, P, Pr), get_dict(low, P, Low), '
        'get_dict(high, P, High), get_dict(n, P, N)')
    scenario = str(solutions[0]['S'])
    cells = {key(task, {n: s[var(n)] for n, _ in task.grid}):
             {'p': s['Pr'], 'low': s['Low'], 'high': s['High'], 'n': s['N']}
             for s in solutions}
    top = max(c['low'] for c in cells.values())
    tied = [c for c, v in cells.items() if v['low'] == top]
    amount: dict[tuple[float, ...], float] = {}
    if task.amount and len(tied) > 1:
        # The same worlds of the same scenario: the projections outcome_probability made.
        for cell in tied:
            values = bench.all(
                f'S = {scenario}, make_projection(S, {task.program}, '
                f'{task.params(dict(zip((n for n, _ in task.grid), cell)))}, '
                f'[samples({cells[cell]["n"]}), seed({seed}), timeout({bench.timeout:g})], '
                f'TL), {task.measures}')
            amount[cell] = statistics.mean(float(v[task.amount]) for v in values)
    bench.drop(solutions)
    return best(task, tied, list(cells), amount or None), cells, amount


def execute(bench: Bench, task: Task, cell: tuple[float, ...], objects: int, seed: int,
            physics: dict[str, int]) -> list[dict[str, float]]:
    """``cell`` done on each of ``objects`` true objects (worlds of the truth's ``seed``) at
    ``physics``: per object its measures and its true properties."""
    dict_ = ', '.join(f'{k}: {v}' for k, v in physics.items())
    sampled = ', '.join(f'quantity(sampled({e}, {k}), T{i}, TL)'
                        for i, (e, k, _) in enumerate(task.truth))
    solutions = bench.all(
        f'{task.set_up(task.truth)}, make_projection(S, {task.program}, '
        f'{task.params(dict(zip((n for n, _ in task.grid), cell)))}, '
        f'[samples({objects}), seed({seed}), physics(_{{{dict_}}}), '
        f'timeout({bench.timeout:g})], TL), {sampled}, {task.measures}')
    bench.drop(solutions)
    if len(solutions) != objects:
        raise RuntimeError(f'{len(solutions)} of {objects} executions answered')
    return [{**measured(task, s), **{f'T{i}': float(s[f'T{i}'])
                                      for i in range(len(task.truth))}} for s in solutions]


# --- one task ---------------------------------------------------------------------------
NAMES = {'a': '(a) default', 'b': '(b) nominal', 'c': '(c) belief'}


def say(text: str = '') -> None:
    print(text, flush=True)


def run_task(bench: Bench, task: Task, objects: int, samples: int, seed: int,
             truth_seed: int, repeat: int) -> None:
    """Decide by each policy, execute each choice on the true objects, print the tables."""
    from projection_server.reproduce.fidelity import reference_physics

    physics = reference_physics(bench.client, task.program)   # 4x rate and iterations
    say()
    say(f'{task.name}: {task.program} in {task.scenario}; {objects} true objects, executed '
        f'at {physics}')
    say('  belief: ' + ', '.join(f'{e} {k} {d}' for e, k, d in task.belief))
    say('  truth:  ' + ', '.join(f'{e} {k} {d}' for e, k, d in task.truth))
    say('  grid:   ' + ' x '.join(f'{n} {list(v)}' for n, v in task.grid))
    say(f'  (c): samples({samples}), decide({decide_threshold(samples):.4f}), seeds '
        f'{seed}..{seed + repeat - 1}; truth seed {truth_seed}; {repeat} timed decisions '
        'of (b) and (c)')
    cells = [tuple(c) for c in _product([values for _, values in task.grid])]
    default = bench.defaults(task)
    if default not in cells:
        raise RuntimeError(f'the default {default} is not in the grid')

    choices: dict[str, list[tuple[float, ...] | None]] = {'a': [default], 'b': [], 'c': []}
    timings: dict[str, list[float]] = {'a': [0.0], 'b': [], 'c': []}
    projections: dict[str, list[int]] = {'a': [0], 'b': [], 'c': []}
    outcomes: dict = {}
    probabilities: dict = {}
    amounts: dict = {}
    for r in range(repeat):
        bags, start = bench.bags(), time.perf_counter()
        result = nominal(bench, task)
        choices['b'].append(choose_nominal(task, result))
        timings['b'].append(time.perf_counter() - start)
        projections['b'].append(bench.bags() - bags)
        outcomes = outcomes or result
    for r in range(repeat):
        bags, start = bench.bags(), time.perf_counter()
        choice, cells_p, amount = belief(bench, task, samples, seed + r)
        choices['c'].append(choice)
        timings['c'].append(time.perf_counter() - start)
        projections['c'].append(bench.bags() - bags)
        if not probabilities:
            probabilities, amounts = cells_p, amount
    for policy in 'bc':
        say(f'  {NAMES[policy]} decisions: ' + '; '.join(
            f'{shown(task, c) if c else "none"} ({t:.1f} s, {p} projections)'
            for c, t, p in zip(choices[policy], timings[policy], projections[policy])))
    grid_tables(task, outcomes, probabilities, amounts, samples, choices)

    executed: dict[tuple[float, ...], list[dict[str, float]]] = {}
    for policy in 'abc':
        cell = choices[policy][0]
        if cell is not None and cell not in executed:
            start = time.perf_counter()
            executed[cell] = execute(bench, task, cell, objects, truth_seed, physics)
            say(f'  executing {shown(task, cell)} on {objects} objects: '
                f'{time.perf_counter() - start:.1f} s')
    first = next(iter(executed.values()))
    for i, (entity, prop, _) in enumerate(task.truth):
        values = sorted(o[f'T{i}'] for o in first)
        say(f'  true {entity} {prop}: min {values[0]:.3g}, median '
            f'{statistics.median(values):.3g}, max {values[-1]:.3g}')

    say()
    say(f'  {"policy":12} {"choice":34} {"undesired":>9} {"95 % interval":>14}'
        + ''.join(f'{u.lower():>7}' for u in task.undesired)
        + ''.join(f'{e.lower() + " median (range)":>24}' for e in task.extra)
        + f' {"projections":>12} {"s/decision":>11}')
    undesired: dict[str, list[bool]] = {}
    for policy in 'abc':
        cell = choices[policy][0]
        if cell is None:
            say(f'  {NAMES[policy]:12} no cell of the grid is ok in the nominal world')
            continue
        runs = executed[cell]
        bad = undesired[policy] = [any(o[u] for u in task.undesired) for o in runs]
        low, high = wilson(sum(bad), len(bad))
        say(f'  {NAMES[policy]:12} {shown(task, cell):34} {sum(bad):>4}/{len(bad):<4} '
            f'{100 * low:5.1f}-{100 * high:5.1f} %'
            + ''.join(f'{int(sum(o[u] for o in runs)):>7}' for u in task.undesired)
            + ''.join(f'{spread([o[e] for o in runs]):>24}' for e in task.extra)
            + f' {statistics.median(projections[policy]):>12g} '
              f'{statistics.median(timings[policy]):>11.2f}')
    for x, y in (('a', 'c'), ('b', 'c'), ('a', 'b')):
        if x in undesired and y in undesired:
            pairs = list(zip(undesired[x], undesired[y]))
            say(f'  the same objects, {x} vs {y}: undesired under {x} only '
                f'{sum(p and not q for p, q in pairs)}, under {y} only '
                f'{sum(q and not p for p, q in pairs)}')
    if 'a' in undesired and 'c' in undesired:
        a, c = sum(undesired['a']), sum(undesired['c'])
        b = sum(undesired['b']) if 'b' in undesired else math.inf
        met = c <= a / 2 and c <= b
        say(f'  goal, (c) at most half of (a) and at most (b): {c} <= {a / 2:g} and '
            f'{c} <= {b:g}: {"met" if met else "not met"}'
            + (' (vacuously: (a) has none)' if a == 0 else ''))


def spread(values: list[float]) -> str:
    return (f'{statistics.median(values):.3g} ({min(values):.3g}-{max(values):.3g})')


def _product(lists: list[tuple[float, ...]]) -> list[list[float]]:
    out: list[list[float]] = [[]]
    for values in lists:
        out = [o + [v] for o in out for v in values]
    return out


def grid_tables(task: Task, outcomes: dict, probabilities: dict, amounts: dict,
                samples: int, choices: dict) -> None:
    """The nominal world's outcome and the belief's P(ok) of every cell: a column per value
    of the grid's first parameter, a row per value of the others; [x]: the choice."""
    (first, columns), rest = task.grid[0], task.grid[1:]
    rows = _product([values for _, values in rest])

    def table(title: str, text, chosen) -> None:
        say(f'  {title}')
        say(f'    {"":26}' + ''.join(f'{f"{first} {v:g}":>12}' for v in columns))
        for row in rows:
            label = ', '.join(f'{n} {v:g}' for (n, _), v in zip(rest, row))
            cells = [(c, *row) for c in columns]
            say(f'    {label:26}' + ''.join(
                f'{(f"[{text(c)}]" if c == chosen else text(c)):>12}' for c in cells))

    def nominal_text(cell) -> str:
        m = outcomes[cell]
        what = '+'.join(u.lower() for u in task.undesired if m[u]) or 'ok'
        return f'{what} {m[task.amount]:g}' if task.amount else what

    def belief_text(cell) -> str:
        p = probabilities[cell]
        text = f'{p["p"]:.2f}' + (f'/{p["n"]}' if p['n'] != samples else '')
        return text + (f' {amounts[cell]:.0f}' if cell in amounts else '')

    amount = f' and {task.amount.lower()}' if task.amount else ''
    table(f'nominal world: outcome{amount}', nominal_text, choices['b'][0])
    table('belief: P(ok) (/n: fewer worlds)'
          + (f', mean {task.amount.lower()} of the best' if task.amount else ''),
          belief_text, choices['c'][0])


def main() -> int:
    parser = harness.arguments(__doc__, seed=1)
    parser.add_argument('--eggs', type=int, default=200, help='true eggs grasped (200)')
    parser.add_argument('--samples', type=int, default=30,
                        help='worlds of the belief per grasp cell, policy (c) (30)')
    parser.add_argument('--repeat', type=int, default=3,
                        help='timed decisions of (b) and (c), grasp (3)')
    parser.add_argument('--pours', type=int, default=20, help='true pours (20)')
    parser.add_argument('--pour-samples', type=int, default=8,
                        help='worlds of the belief per pour cell, policy (c) (8)')
    parser.add_argument('--pour-repeat', type=int, default=1,
                        help='timed decisions of (b) and (c), pour (1)')
    parser.add_argument('--truth-seed', type=int, default=2026,
                        help='seed of the true objects (2026)')
    parser.add_argument('--only', choices=('grasp', 'pour'), help='one task')
    parser.add_argument('--workers', type=int, default=2)
    args = parser.parse_args()
    harness.ros_domain(150)

    import rclpy

    tasks = [(GRASP, args.eggs, args.samples, args.repeat),
             (POUR, args.pours, args.pour_samples, args.pour_repeat)]
    say(f'closed_loop: policies (a) default, (b) nominal world, (c) belief, each executed on '
        f'the same true objects at 4x the rate and solver iterations; {args.workers} workers, '
        f'a fresh bag_dir; seed {args.seed}, truth seed {args.truth_seed}; {harness.machine()}')
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
                for task, objects, samples, repeat in tasks:
                    if args.only in (None, task.name):
                        start = time.perf_counter()
                        run_task(bench, task, objects, samples, args.seed, args.truth_seed,
                                 repeat)
                        say(f'  {task.name}: {time.perf_counter() - start:.0f} s')
    finally:
        rclpy.try_shutdown()
    say()
    say(f'closed_loop: {time.perf_counter() - started:.0f} s in all; {harness.machine()}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
