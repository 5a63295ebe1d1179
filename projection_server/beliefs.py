"""What a robot does not know exactly: properties given as distributions, the nominal world,
and the worlds drawn from them.

A scenario property may be a distribution instead of a number (Prolog's ``uniform(L, H)``,
``normal(Mean, SD)``, ``choice(Values)``; in the scenario description a dict
``{'distribution': 'uniform', 'low': L, 'high': H}``, ``{'distribution': 'normal', 'mean':
M, 'sd': S}``, ``{'distribution': 'choice', 'values': [...]}``). Each is truncated to its
property's valid range (:data:`RANGES`, by the property's kind in the object class
registry): friction at least 0, restitution within [0, 1], a mass above 0.

The worker projects a plain world and knows nothing of beliefs: before a job is made, the
description's distributions are replaced by numbers here, in the projection layer, either by
their nominal values (:func:`nominal`: a projection without samples: a uniform
distribution's middle, a normal one's mean, a choice's mean, within the range) or by the draws of world ``index``
of the sequence ``seed`` (:func:`world`: the same seed and index draw the same numbers,
whichever parametrization or backend asks). Distributions are drawn in the order of their
entity's name and property key, each world from its own stream of ``numpy``'s
``default_rng([seed, index])``; a truncated normal by inverting its distribution function.
"""

from __future__ import annotations

import copy
import math
from statistics import NormalDist
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation import objects
from projection_server.simulation.objects.registry import (ANY, FRACTION, NONNEGATIVE,
                                                           POSITIVE)

if TYPE_CHECKING:
    from collections.abc import Iterator

__all__ = ['RANGES', 'has_beliefs', 'nominal', 'problem', 'world']

# A property kind's valid range, where its distributions are truncated to.
RANGES = {POSITIVE: (1e-12, math.inf), NONNEGATIVE: (0.0, math.inf), FRACTION: (0.0, 1.0),
          ANY: (-math.inf, math.inf)}
_LEAST_MASS = 1e-9   # of a distribution inside its range: less is wholly outside
_STANDARD = NormalDist()


def problem(cls: str, key: str, belief: dict[str, Any]) -> str | None:
    """What is wrong with ``belief`` as the value of property ``key`` of class ``cls``
    (None: nothing): a property that is no number, a distribution of no known form, an SD
    not above 0, an empty or reversed range, or one wholly outside the property's range."""
    try:
        low, high = _range(cls, key)
        _truncated(belief, low, high)
    except ProjectionError as exc:
        return exc.message
    return None


def has_beliefs(description: dict[str, Any]) -> bool:
    """Whether any property of the scenario description is a distribution."""
    return any(True for _ in _beliefs(description))


def nominal(description: dict[str, Any]) -> dict[str, Any]:
    """The description with each distribution replaced by its nominal value (a uniform
    one's middle, a normal one's mean, a choice's mean; within the property's range); the
    description itself when it has none."""
    found = list(_beliefs(description))
    if not found:
        return description
    out = copy.deepcopy(description)
    for entity, key, belief in _beliefs(out):
        low, high = _range(entity['class'], key)
        entity['properties'][key] = _truncated(belief, low, high).nominal()
    return out


def world(description: dict[str, Any], seed: int, index: int
          ) -> tuple[dict[str, Any], list[tuple[str, str, float]]]:
    """World ``index`` of the sequence ``seed``: the description with each distribution
    replaced by a draw, and the draws as ``(entity, property, value)``."""
    out = copy.deepcopy(description)
    found = sorted(_beliefs(out), key=lambda b: (b[0]['name'], b[1]))
    rng = np.random.default_rng([int(seed), int(index)])
    drawn = []
    for entity, key, belief in found:
        low, high = _range(entity['class'], key)
        value = _truncated(belief, low, high).draw(rng)
        entity['properties'][key] = value
        drawn.append((entity['name'], key, value))
    return out, drawn


def _beliefs(description: dict[str, Any]) -> Iterator[tuple[dict[str, Any], str, dict]]:
    """``(entity, key, belief)`` of every distribution in the description, parts included."""
    stack = list(description.get('entities', []))
    while stack:
        entity = stack.pop()
        for key, value in entity.get('properties', {}).items():
            if isinstance(value, dict) and 'distribution' in value:
                yield entity, key, value
        stack.extend(entity.get('parts', []))


def _range(cls: str, key: str) -> tuple[float, float]:
    if cls in objects.names():
        for prop in objects.get(cls).properties:
            if prop.name == key and prop.kind in RANGES:
                return RANGES[prop.kind]
    raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                          f'{cls} has no numeric property {key!r} that may be uncertain')


class _Uniform:
    def __init__(self, low: float, high: float):
        self.low, self.high = low, high

    def nominal(self) -> float:
        return (self.low + self.high) / 2

    def draw(self, rng: np.random.Generator) -> float:
        return float(self.low + (self.high - self.low) * rng.random())


class _Normal:
    def __init__(self, mean: float, sd: float, low: float, high: float):
        self.mu, self.sd = mean, sd
        self.a = _STANDARD.cdf((low - mean) / sd) if math.isfinite(low) else 0.0
        self.b = _STANDARD.cdf((high - mean) / sd) if math.isfinite(high) else 1.0
        self.low, self.high = low, high

    def nominal(self) -> float:
        """The mean, within the range (not the truncated distribution's mean: a belief
        normal(0.35, 0.05) of a friction is nominally 0.35, as a plain 0.35 would be)."""
        return min(max(self.mu, self.low), self.high)

    def draw(self, rng: np.random.Generator) -> float:
        u = self.a + (self.b - self.a) * rng.random()
        u = min(max(u, 1e-16), 1 - 1e-16)
        return float(min(max(self.mu + self.sd * _STANDARD.inv_cdf(u), self.low), self.high))


class _Choice:
    def __init__(self, values: list[float]):
        self.values = values

    def nominal(self) -> float:
        return float(sum(self.values) / len(self.values))

    def draw(self, rng: np.random.Generator) -> float:
        return float(self.values[int(rng.integers(len(self.values)))])


def _truncated(belief: dict[str, Any], low: float, high: float) -> Any:
    """The distribution of ``belief`` truncated to [low, high]."""
    kind = belief.get('distribution')

    def number(name: str) -> float:
        value = belief.get(name)
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or not math.isfinite(value)):
            _invalid(f'{kind}: {name} must be a finite number, got {value!r}')
        return float(value)

    if kind == 'uniform':
        a, b = number('low'), number('high')
        if not a < b:
            _invalid(f'uniform({a:g}, {b:g}): its low end must be below its high end')
        if b <= low or a >= high:
            _invalid(f'uniform({a:g}, {b:g}) lies wholly outside [{low:g}, {high:g}]')
        return _Uniform(max(a, low), min(b, high))
    if kind == 'normal':
        mean, sd = number('mean'), number('sd')
        if not sd > 0:
            _invalid(f'normal({mean:g}, {sd:g}): its SD must be above 0')
        normal = _Normal(mean, sd, low, high)
        if normal.b - normal.a < _LEAST_MASS:
            _invalid(f'normal({mean:g}, {sd:g}) lies wholly outside [{low:g}, {high:g}]')
        return normal
    if kind == 'choice':
        values = belief.get('values')
        if not isinstance(values, list) or not values:
            _invalid('choice needs a non-empty list of numbers')
        checked = [_number_of(v) for v in values]
        outside = [v for v in checked if not low <= v <= high]
        if outside:
            _invalid(f'choice({checked}): {outside[0]:g} is outside [{low:g}, {high:g}]')
        return _Choice(checked)
    _invalid(f'unknown distribution {kind!r} (known: uniform, normal, choice)')


def _number_of(value: Any) -> float:
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not math.isfinite(value)):
        _invalid(f'choice: {value!r} is no finite number')
    return float(value)


def _invalid(message: str):
    raise ProjectionError(ErrorKind.INVALID_SCENARIO, message)
