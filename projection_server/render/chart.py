"""A chart of a projection's timeline: one row per object, its fluents as bars over time,
its events as marks with their names, the time axis in seconds.

A fluent or event is drawn in the row of every object it names (``contact(egg1, table1)``
in ``egg1``'s and in ``table1``'s); within a row each fluent term has a lane of its own (a
colour per fluent name), and the events, if any, a lane below them.

    >>> rows = timeline_chart(timeline, 'timeline.png')   # ['egg1', 'panda_robot', ...]
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Mapping

__all__ = ['chart_rows', 'term_text', 'timeline_chart']

_PALETTE = ('#4c72b0', '#55a868', '#8172b2', '#ccb974', '#64b5cd', '#8c8c8c', '#da8bc3')
_EVENT = '#c44e52'
_SHADES = ('#ffffff', '#efefef')


def term_text(name: str, args: list[Any]) -> str:
    """A fluent's or event's term as Prolog writes it: ``grasp(egg1)``."""
    return f'{name}({", ".join(str(a) for a in args)})' if args else str(name)


def chart_rows(timeline: Mapping[str, Any]) -> list[tuple[str, list[str], list[tuple]]]:
    """The chart's rows: ``(object, fluent terms (its lanes), events)``, objects by name;
    events as ``(term, start, end)``."""
    lanes: dict[str, list[str]] = {}
    events: dict[str, list[tuple]] = {}
    for name, args, start, end in timeline.get('fluents', []):
        term = term_text(name, args)
        for obj in _objects(args):
            row = lanes.setdefault(obj, [])
            if term not in row:
                row.append(term)
            events.setdefault(obj, [])
    for name, args, start, end in timeline.get('events', []):
        for obj in _objects(args):
            lanes.setdefault(obj, [])
            events.setdefault(obj, []).append((term_text(name, args), start, end))
    return [(obj, sorted(lanes[obj]), sorted(events[obj], key=lambda e: e[1]))
            for obj in sorted(lanes)]


def timeline_chart(timeline: Mapping[str, Any], path: str | Path, *,
                   title: str = '', width: float = 10.0) -> list[str]:
    """Draw ``timeline`` (fluents and events as :func:`~projection_server.timeline.
    translate_records` gives them) into a PNG at ``path``; its rows' objects, top down."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    rows = chart_rows(timeline)
    fluents = timeline.get('fluents', [])
    ends = [float(f[3]) for f in fluents] + [float(e[3]) for e in timeline.get('events', [])]
    duration = max([float(timeline.get('meta', {}).get('duration') or 0.0), *ends, 1e-3])
    spans: dict[str, list[tuple[float, float]]] = {}   # fluent term -> its intervals
    colors: dict[str, str] = {}                         # fluent name -> its bars' colour
    for name, args, start, end in fluents:
        spans.setdefault(term_text(name, args), []).append((float(start), float(end)))
        colors.setdefault(name, _PALETTE[len(colors) % len(_PALETTE)])
    n_lanes = sum(len(lanes) + bool(events) for _, lanes, events in rows) or 1
    fig, ax = plt.subplots(figsize=(width, 1.0 + 0.3 * n_lanes))
    y, ticks, labels = 0, [], []
    for index, (obj, lanes, row_events) in enumerate(rows):
        top = y
        for term in lanes:
            for start, end in spans[term]:
                # A fluent that holds for one sample still shows as a sliver.
                ax.barh(y, max(end - start, duration / 400), left=start, height=0.7,
                        color=colors[term.split('(')[0]])
            ax.text(duration * 1.01, y, term, va='center', fontsize=7)
            y += 1
        if row_events:
            for k, (term, start, end) in enumerate(row_events):
                if end > start:
                    ax.plot([start, end], [y, y], color=_EVENT, lw=2)
                ax.plot([start], [y], marker='v', color=_EVENT, ms=6)
                # Labels of events close in time alternate above and below the mark.
                ax.annotate(term, (start, y), xytext=(3, -8 if k % 2 else 3),
                            textcoords='offset points', fontsize=7, color=_EVENT)
            ax.text(duration * 1.01, y, 'events', va='center', fontsize=7, color=_EVENT)
            y += 1
        ax.axhspan(top - 0.5, y - 0.5, color=_SHADES[index % 2], zorder=0)
        ax.axhline(y - 0.5, color='#999999', lw=0.6)
        ticks.append((top + y - 1) / 2)
        labels.append(obj)
    ax.set_yticks(ticks, labels, fontsize=9)
    ax.set_ylim(max(y, 1) - 0.5, -0.5)
    ax.set_xlim(0.0, duration)
    ax.set_xlabel('time [s]')
    ax.grid(axis='x', lw=0.3)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.subplots_adjust(right=0.78)
    fig.savefig(Path(path), dpi=100)
    plt.close(fig)
    return [obj for obj, _, _ in rows]


def _objects(args: list[Any]) -> list[str]:
    return list(dict.fromkeys(a for a in args if isinstance(a, str)))
