"""One projection as a worker makes it: simulate, then the timeline of what was logged.

The simulation (:mod:`projection_server.simulation`) writes the bag and keeps its monitor's
records; the timeline (:mod:`projection_server.timeline`) is made from those records here,
in the worker that has them in memory. :func:`translate_bag` makes the same timeline from a
bag on disk (an older log), from the records read back from it.

    >>> timeline = run_projection(job, load_settings(), Path('/tmp/bag'))
    >>> translate_bag('/tmp/bag') == timeline
    True
"""

from __future__ import annotations

import json
import os
import time
from typing import Any, TYPE_CHECKING

from projection_server.bags import read_records
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.runner import collector_paused, Simulator
from projection_server.simulation.scenario import parse_scenario
from projection_server.timeline import translate_records

if TYPE_CHECKING:
    from pathlib import Path

    from projection_server.settings import Settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Projection

__all__ = ['project', 'run_projection', 'timeline_of', 'translate_bag']


def timeline_of(projection: Projection, bag: str | os.PathLike[str]) -> dict[str, Any]:
    """The timeline of a finished ``projection`` whose bag is ``bag``, from its records.

    Without the cyclic garbage collector (:func:`collector_paused`): a grasp's timeline set
    off about seven young collections, 5 ms of a MuJoCo projection's 80 (bench/RESULTS.md).
    """
    with collector_paused():
        return translate_records(projection.monitor.records, bag, projection.scenario)


def project(simulator: Simulator, job: Job, settings: Settings, bag: Path,
            spent: dict[str, float] | None = None) -> dict[str, Any]:
    """Simulate ``job`` on ``simulator`` into a new bag at ``bag``; its timeline. With
    ``spent``, the CPU seconds of the simulation and of the timeline go into it
    (``sim_cpu``, ``timeline_cpu``).

    The collector stays paused from the simulation's start to the timeline's end: a
    collection in between would traverse the whole finished projection, which the
    timeline still reads."""
    with collector_paused():
        if spent is None:
            return timeline_of(simulator.run(job, settings, bag), bag)
        cpu = time.process_time()
        projection = simulator.run(job, settings, bag)
        middle = time.process_time()
        timeline = timeline_of(projection, bag)
        spent.update(sim_cpu=middle - cpu, timeline_cpu=time.process_time() - middle)
        return timeline


def run_projection(job: Job, settings: Settings, bag: Path) -> dict[str, Any]:
    """:func:`project` with a PyBullet client of its own (e.g. from a debugger)."""
    simulator = Simulator()
    try:
        return project(simulator, job, settings, bag)
    finally:
        simulator.close()


def translate_bag(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The timeline of the projection logged in the bag at ``path``: the one its worker
    made, from the records read back from the bag.

    Raises:
        ProjectionError: kind ``bag_error`` if the bag cannot be read or is not a
            projection's.
    """
    records = list(read_records(path))
    info = next((r.data for r in records if r.kind == 'info'), None)
    if info is None:
        raise ProjectionError(ErrorKind.BAG_ERROR, f'{path}: no projection info')
    try:
        scenario = parse_scenario(json.loads(info.scenario_json))
    except (ValueError, ProjectionError) as exc:
        raise ProjectionError(ErrorKind.BAG_ERROR,
                              f'{path}: its scenario cannot be read: {exc}') from exc
    return translate_records(records, path, scenario)
