"""The messages on a worker process's pipe, by name.

The parent (a slot of the ``local`` backend, or a Ray actor) sends commands; the worker
process (:mod:`projection_server.workers.process`) answers each with messages that carry
``result`` and ``ok``, as Gymnasium's ``AsyncVectorEnv`` does: a failure is a
:class:`~projection_server.errors.ProjectionError` in ``result`` with ``ok`` False, never an
exception in the parent.

========================  =====================================================
command                   answers
========================  =====================================================
:class:`Start`            :class:`Ready` (first message to an exec'd process)
:class:`Project`          :class:`Result`
:class:`Tree`             a :class:`LeafResult` per projection as it ends, then
                          :class:`TreeEnded`; meanwhile :class:`Project` is
                          answered with :class:`Result` (the tree paused)
:class:`Close`            none: the process exits
========================  =====================================================

A process started by multiprocessing gets its settings as arguments and sends
:class:`Ready` first, unasked. All are plain named tuples: picklable, and cheap to send.
"""

from __future__ import annotations

from typing import Any, NamedTuple, TYPE_CHECKING, Union

if TYPE_CHECKING:
    from projection_server.simulation.job import Job

__all__ = ['Answer', 'Close', 'Command', 'LeafResult', 'Project', 'Ready', 'Result', 'Start',
           'Tree', 'TreeEnded']


class Start(NamedTuple):
    """The settings of a worker process started by exec (a Ray actor's)."""

    settings: dict[str, Any]
    warm: bool


class Project(NamedTuple):
    """Run ``job`` into a bag at the path ``bag``."""

    job: Job
    bag: str


class Tree(NamedTuple):
    """Run ``leaves`` (a job and a bag path each, one family) as one tree."""

    leaves: list[tuple[Job, str]]


class Close(NamedTuple):
    """Exit (a running tree goes with the process)."""


class Ready(NamedTuple):
    """Started: ``{'warm_up': report or None}``, or why not."""

    result: Any
    ok: bool


class Result(NamedTuple):
    """A :class:`Project`'s projection: its timeline, or its error."""

    result: Any
    ok: bool


class LeafResult(NamedTuple):
    """The projection ``index`` of a :class:`Tree`: its timeline, or its error."""

    index: int
    result: Any
    ok: bool


class TreeEnded(NamedTuple):
    """A :class:`Tree` has ended; ``complete`` is False if a process of the tree ended
    before it reported (the projections it did not report are to be run again)."""

    complete: bool


Command = Union[Project, Tree, Close]
Answer = Union[Ready, Result, LeafResult, TreeEnded]
