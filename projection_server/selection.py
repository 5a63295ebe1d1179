"""Choosing among parametrizations under a belief, and certifying the choice on fresh worlds:
the statistics of ``robust_parametrization/7`` (``prolog/robust.pl``).

Prolog projects; this module decides, from plain outcome lists, and keeps no state. A
cell is a parametrization; ``outcomes[c]`` lists whether the condition held (1) or not (0)
in each choosing world so far, the same worlds for every cell (common random numbers: world
i of the seed is the same for every cell), or is None once the cell is eliminated.

After each round, :func:`step` eliminates a cell when, at ``confidence`` C with Bonferroni's
correction over the k - 1 comparisons (alpha = (1 - C) / (k - 1)):

* **paired**: another surviving cell b did better in the worlds where the two differ, by an
  exact one-sided sign test (McNemar's) on those discordant worlds; or
* **risk**: its one-sided Clopper-Pearson upper bound is below 1 - A (it could not be
  certified at risk A), while another surviving cell's is not.

Neither rule depends on the cells' order. Choosing stops when one cell is left, at
``max_worlds``, or when it is settled: the leading cells (the most successes) have agreed in
every world for as many worlds as the sign test needs to part two cells, and every other
survivor is observed to be worse than them by more than the indifference zone. More
worlds of the same kind would hardly change the choice; the certificate, on fresh worlds,
is what proves it. A rule that takes an edge of the equals (``prefer``, ``near``) takes the
one cell of them that more worlds are likeliest to part from the rest (the gentlest grip is
the first to slip), so under it a settled choosing goes on until the leaders have agreed in
as many worlds as the certificate has (``settle``), so that the choice has held in as many
worlds as its certificate will ask of it. Only the two leaders the rule ranks first go on
(``ranked``); the others are *parked* with the worlds they have, to be taken only if both
fail.

:func:`choose` then takes the *equals*, the survivors whose observed probability is within
the indifference zone D of the best's, and picks one by a rule (:data:`RULES`), and
:func:`certificate` judges the choice from fresh worlds only.
"""

from __future__ import annotations

import functools
import math
from typing import Any, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = ['RULES', 'certificate', 'certify_count', 'choose', 'clopper_pearson', 'first_round',
           'sign_test', 'step']

RULES = ('margin', 'near', 'prefer')
# The certifying worlds of seed K are K's worlds from here on; the choosing ones from 0.
CERTIFY_OFFSET = 1_000_000


def certify_count(risk: float, confidence: float) -> int:
    """The fewest fresh worlds that can prove P(fail) <= ``risk`` at ``confidence`` (all
    of them successes; one-sided Clopper-Pearson): 59 for 0.05 at 0.95."""
    return math.ceil(math.log(1.0 - confidence) / math.log(1.0 - risk) - 1e-12)


# A choice's rounds ask for the same few bounds and tests again and again (a bisection each).
@functools.lru_cache(maxsize=4096)
def clopper_pearson(k: int, n: int, confidence: float) -> tuple[float, float]:
    """The one-sided Clopper-Pearson lower and upper bounds of a proportion of ``k`` in
    ``n``, each at ``confidence`` (together a two-sided interval at 2C - 1)."""
    alpha = 1.0 - confidence
    low = 0.0 if k == 0 else _solve(lambda p: _upper_tail(k, n, p) - alpha)
    high = 1.0 if k == n else _solve(lambda p: alpha - _lower_tail(k, n, p))
    return low, high


@functools.lru_cache(maxsize=4096)
def sign_test(u: int, v: int) -> float:
    """One-sided exact sign test: P(at least ``u`` of ``u + v`` fair coin flips)."""
    return _upper_tail(u, u + v, 0.5) if u + v else 1.0


def first_round(cells: int, confidence: float, risk: float, batch: int) -> int:
    """The worlds of the first round: ``batch``, and at least as many as the risk rule
    needs to eliminate a cell that fails in all of them."""
    alpha = _alpha(cells, confidence)
    least = math.floor(math.log(alpha) / math.log(risk)) + 1
    return max(batch, least)


def step(outcomes: Sequence[Sequence[int] | None], confidence: float, risk: float,
         indifference: float, max_worlds: int, settle: int = 0,
         ranked: Sequence[int] = ()) -> dict[str, Any]:
    """The cells to eliminate after a round, those to park, and whether choosing stops
    (module doc). ``settle``: the fewest worlds of a settled stop, beyond those the sign test
    needs; ``ranked``: the equals in the rule's order (:func:`choose`), which an edge rule
    gives with its ``settle``."""
    alive = [c for c, o in enumerate(outcomes) if o is not None]
    n = len(outcomes[alive[0]])
    alpha = _alpha(len(outcomes), confidence)
    eliminate = set()
    if len(alive) > 1:
        highs = {c: clopper_pearson(sum(outcomes[c]), n, 1.0 - alpha)[1] for c in alive}
        certifiable = [c for c in alive if highs[c] >= 1.0 - risk]
        for c in alive:
            if certifiable and highs[c] < 1.0 - risk:
                eliminate.add(c)
                continue
            for b in alive:
                u = sum(1 for x, y in zip(outcomes[b], outcomes[c]) if x > y)
                v = sum(1 for x, y in zip(outcomes[b], outcomes[c]) if x < y)
                if b != c and sign_test(u, v) <= alpha:
                    eliminate.add(c)
                    break
    left = [c for c in alive if c not in eliminate]
    rate = {c: sum(outcomes[c]) / n for c in left}
    top = max(rate.values())
    leaders = [c for c in left if rate[c] == top]
    settled = (all(outcomes[c] == outcomes[leaders[0]] for c in leaders)
               and all(rate[c] < top - indifference for c in left if c not in leaders))
    separable = math.ceil(math.log2(1.0 / alpha)) if len(outcomes) > 1 else 0
    stop = len(left) <= 1 or n >= max_worlds or (settled and n >= max(separable, settle))
    park: list[int] = []
    if settled and n >= separable and not stop and ranked:
        keep = [c for c in ranked if c in leaders][:2]
        park = [c for c in leaders if c not in keep]
    return {'eliminate': sorted(eliminate), 'park': sorted(park), 'stop': stop}


def choose(outcomes: Sequence[Sequence[int] | None], values: Sequence[Sequence[float]],
           indifference: float, rule: str, *, near: Sequence[float] | None = None,
           quantities: Sequence[float | None] | None = None, sign: int = 1
           ) -> dict[str, Any]:
    """The chosen cell among the equals (module doc) by ``rule``:

    * ``margin``: the one farthest from any cell that failed in some world or was
      eliminated, in the parameters' space scaled by each one's span in the grid;
    * ``near``: the one nearest ``near`` (e.g. the program's defaults, to keep them when
      they are among the equals);
    * ``prefer``: the one with the greatest mean quantity times ``sign`` (``quantities``,
      one per cell, None for eliminated ones).

    Ties left go to ``margin``, then to the equal nearest the equals' centre, then to the
    smallest values: never to the grid's order. Returns the cell, the equals, the equals
    in the rule's order (``ranked``, the cell first) and the observed probability of each
    survivor. A cell's outcomes may be fewer than others' (a parked one).
    """
    alive = [c for c, o in enumerate(outcomes) if o is not None]
    rate = {c: sum(outcomes[c]) / len(outcomes[c]) for c in alive}
    top = max(rate.values())
    equals = [c for c in alive if rate[c] >= top - indifference - 1e-12]
    spans = [max(v[i] for v in values) - min(v[i] for v in values) or 1.0
             for i in range(len(values[0]))]

    def distance(a: Sequence[float], b: Sequence[float]) -> float:
        return math.hypot(*((x - y) / s for x, y, s in zip(a, b, spans)))

    failed = [c for c in range(len(outcomes)) if outcomes[c] is None or rate[c] < 1.0]
    margin = {c: min((distance(values[c], values[f]) for f in failed), default=math.inf)
              for c in equals}
    centre = [sum(values[c][i] for c in equals) / len(equals) for i in range(len(spans))]

    def key(c: int) -> tuple:
        first: float = 0.0
        if rule == 'near':
            first = -distance(values[c], near)
        elif rule == 'prefer':
            first = sign * quantities[c]
        return (round(first, 12), round(margin[c], 12), -distance(values[c], centre),
                [-x for x in values[c]])

    ranked = sorted(equals, key=key, reverse=True)
    return {'cell': ranked[0], 'equals': sorted(equals), 'ranked': ranked,
            'rates': [rate.get(c) for c in range(len(outcomes))]}


def certificate(successes: int, n: int, confidence: float, risk: float) -> dict[str, Any]:
    """The choice judged on ``n`` fresh worlds: the fraction, its one-sided Clopper-Pearson
    bounds at ``confidence`` and whether the lower one proves P(ok) >= 1 - ``risk``."""
    low, high = clopper_pearson(successes, n, confidence)
    return {'p': successes / n, 'low': low, 'high': high, 'n': n,
            'certified': low >= 1.0 - risk - 1e-12}


def _alpha(cells: int, confidence: float) -> float:
    return (1.0 - confidence) / max(1, cells - 1)


def _upper_tail(k: int, n: int, p: float) -> float:
    """P(X >= k), X ~ Binomial(n, p)."""
    return min(1.0, sum(_pmf(i, n, p) for i in range(k, n + 1)))


def _lower_tail(k: int, n: int, p: float) -> float:
    """P(X <= k), X ~ Binomial(n, p)."""
    return min(1.0, sum(_pmf(i, n, p) for i in range(0, k + 1)))


def _pmf(i: int, n: int, p: float) -> float:
    if p <= 0.0:
        return 1.0 if i == 0 else 0.0
    if p >= 1.0:
        return 1.0 if i == n else 0.0
    log = (math.lgamma(n + 1) - math.lgamma(i + 1) - math.lgamma(n - i + 1)
           + i * math.log(p) + (n - i) * math.log1p(-p))
    return math.exp(log)


def _solve(f, low: float = 0.0, high: float = 1.0) -> float:
    """The root of increasing ``f`` on [low, high], by bisection to 1e-12."""
    for _ in range(60):
        mid = (low + high) / 2
        if f(mid) < 0.0:
            low = mid
        else:
            high = mid
    return (low + high) / 2
