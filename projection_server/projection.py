"""Entry point of the simulation side for Prolog: ``simulate``, ``timeline``, ``prefetch``.

One process-wide worker backend (:mod:`projection_server.workers`), created on first use
with the settings given to :func:`configure` (default bag directory: the environment
variable ``PROJECTION_SERVER_BAG_DIR``, else ``~/.cache/projection_server/bags``).

    >>> path = simulate(scenario, 'grasp_object', {'force': 5.0, 'position': 0.0}, 60.0)
    >>> timeline(path)['events']

Projections are owned by the query that asks for them: Prolog passes the query's owner
token (its context, set by the query service) with every call, the projections it submits
are tagged with it, and :func:`cancel` stops them and the query's waits.

The worker that ran a projection also made its timeline; :func:`simulate` keeps it until
:func:`timeline` hands it over (once), so the bag is read back only for older logs.
"""

from __future__ import annotations

import atexit
from collections import OrderedDict
import dataclasses
import itertools
import logging
import os
from pathlib import Path
import threading
import time
from typing import Any, TYPE_CHECKING

from projection_server import beliefs
from projection_server.simulation import programs as _programs
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.job import Job
from projection_server.simulation.scenario import parse_scenario
from projection_server.settings import ENGINES, load_settings
from projection_server.workers import cost, create_backend, Retention

if TYPE_CHECKING:
    from collections.abc import Mapping, Sequence
    from concurrent.futures import Future

    from projection_server.workers import ProjectionResult, WorkerBackend

__all__ = [
    'ProjectionError',
    'cancel',
    'configure',
    'default_bag_dir',
    'drop',
    'belief_problem',
    'physics_settings',
    'prefetch',
    'plan_problem',
    'prefetch_plan',
    'programs',
    'project',
    'release',
    'shutdown',
    'simulate',
    'start',
    'submit',
    'timeline',
    'vocabulary',
    'workers',
]

FAMILY_BATCH = 32   # projections of one family queued at most at once by prefetch_plan
_POLL = 1.0   # s between checks that the backend still runs while waiting for a result

_log = logging.getLogger('projection_server.projection')
_lock = threading.Lock()
_backend: WorkerBackend | None = None
_config: dict[str, Any] = {'bag_dir': None, 'workers': 1, 'retention': None,
                           'backend': 'local', 'ray_address': None, 'engine': None}
# Timelines of finished projections not yet handed to Prolog, by bag path (bounded: a
# query that never asks for its timelines must not grow the process).
_timelines: OrderedDict[str, dict[str, Any]] = OrderedDict()
_KEEP_TIMELINES = 64
# What each bag's world drew from the scenario's distributions, for its timeline.
_drawn: OrderedDict[str, list[tuple[str, str, float]]] = OrderedDict()
_KEEP_DRAWN = 4096
# A stop event per owner (query) that makes its waits end at once when it is cancelled.
_stops: dict[str, threading.Event] = {}


def default_bag_dir() -> Path:
    """``$PROJECTION_SERVER_BAG_DIR``, else ``~/.cache/projection_server/bags``."""
    configured = os.environ.get('PROJECTION_SERVER_BAG_DIR')
    if configured:
        return Path(configured).expanduser()
    return Path.home() / '.cache' / 'projection_server' / 'bags'


def configure(bag_dir: str | os.PathLike[str] | None = None, workers: int | None = None,
              retention: Retention | Mapping[str, Any] | None = None,
              backend: str | None = None, ray_address: str | None = None,
              engine: str | None = None) -> None:
    """Set where bags go, how many workers run projections, how many bags are kept and
    which worker backend runs them (``local`` or ``ray``; ``ray_address`` is the Ray
    cluster to join, ``''`` for a local Ray instance, see :func:`workers.ray.connect`);
    ``engine`` is the physics engine of a query that chooses none (one of
    :data:`~projection_server.settings.ENGINES`; default: the settings file's).

    Arguments left as None keep their current value. ``retention`` is a
    :class:`~projection_server.workers.Retention` or a dict with ``max_bags`` and
    ``max_bytes``. A running backend is closed; a new ``local`` one starts its workers at
    once, so that they are warm when the first projection comes (a ``ray`` one when the
    first projection needs it).
    """
    global _backend
    with _lock:
        if workers is not None and (not isinstance(workers, int) or workers < 1):
            raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'workers must be >= 1, got {workers!r}')
        if engine is not None and engine not in ENGINES:
            raise ProjectionError(ErrorKind.INVALID_SETTINGS,
                                  f'engine must be one of {", ".join(ENGINES)}, got {engine!r}')
        updates = {'bag_dir': bag_dir, 'workers': workers, 'backend': backend,
                   'ray_address': ray_address, 'engine': engine,
                   'retention': Retention.of(retention) if retention is not None else None}
        _config.update({k: v for k, v in updates.items() if v is not None})
        old, _backend = _backend, None
    if old is not None:
        old.close()
    if _config['backend'] == 'local':
        _get_backend()


def project(scenario: dict[str, Any], program: str, params: dict[str, Any],
            timeout: float, owner: str | None = None,
            physics: Mapping[str, Any] | None = None,
            plan: list[Any] | None = None,
            world: Sequence[int] | None = None) -> dict[str, Any]:
    """Run one projection and return ``{'bag': path, 'timeline': timeline or None}``.

    The timeline (the dict of ``docs/contracts.md``) is the one the worker made from its
    samples; it is None when the bag was found in the bag directory, made by an earlier
    process (``translate_bag`` reads it). ``timeout`` is the wall-clock limit of the
    simulation in seconds; ``physics`` chooses engine settings (:func:`physics_settings`)
    over the program's; ``plan`` is the plan of the program ``plan``. A scenario whose
    properties are distributions (:mod:`projection_server.beliefs`) is projected in its
    nominal world, or with ``world`` ``[seed, index]`` in that world drawn from them. An
    identical projection made before (same scenario, program, parameters, settings, plan and
    code) returns the existing bag.

    Raises:
        ProjectionError: with ``kind`` ``invalid_scenario``, ``unknown_program``,
            ``invalid_parameters``, ``timeout``, ``worker_crashed``, ``simulation_failed``,
            ``cancelled``...
    """
    result = _wait(submit(scenario, program, params, timeout, owner, physics, plan, world),
                   owner)
    return {'bag': result.bag, 'timeline': result.timeline}


def simulate(scenario: dict[str, Any], program: str, params: dict[str, Any],
             timeout: float, owner: str | None = None,
             physics: Mapping[str, Any] | None = None,
             plan: list[Any] | None = None,
             world: Sequence[int] | None = None) -> str:
    """Like :func:`project`, but return the path of the bag and keep the timeline for
    :func:`timeline` (with the world's draws as its quantities ``sampled(Entity,
    Property)``)."""
    concrete, drawn = _world(scenario, world)
    job = Job.checked(concrete, program, params, physics, plan)
    _warn_of(job)
    future = _get_backend().submit(job, timeout, owner)
    cached = future.done()   # its bag was made before, or prefetched and is done
    started, asked = time.monotonic(), time.time()
    _log.debug('projection %s %s started', program, params)
    try:
        result = _wait(future, owner)
    except ProjectionError as exc:
        _log.info('projection %s %s failed after %.2f s: %s', program, params,
                  time.monotonic() - started, exc)
        raise
    _log.info('projection %s %s ended in %.2f s%s: %s', program, params,
              time.monotonic() - started, ' (cache hit)' if cached else '', result.bag)
    cost.record('waited', result.bag, asked=asked, got=time.time())
    with _lock:
        if result.timeline is not None:
            _timelines[result.bag] = result.timeline
            while len(_timelines) > _KEEP_TIMELINES:
                _timelines.popitem(last=False)
        if drawn:
            _drawn[result.bag] = drawn
            while len(_drawn) > _KEEP_DRAWN:
                _drawn.popitem(last=False)
    return result.bag


def _warn_of(job: Job) -> None:
    """Log a warning (on /rosout, through the node) of what in ``job``'s scenario cannot
    act as asked: a batter that will not set."""
    from projection_server.simulation.batter.heat import unreachable_setting

    for text in unreachable_setting(parse_scenario(job.scenario)):
        _log.warning('projection %s: %s', job.program, text)


def timeline(bag: str | os.PathLike[str]) -> dict[str, Any]:
    """The timeline of the projection logged in ``bag``: the one its worker made, if
    :func:`simulate` has it, else read from the bag.

    Raises:
        ProjectionError: kind ``bag_error`` if the bag cannot be read or is not a projection.
    """
    with _lock:
        made = _timelines.pop(os.fspath(bag), None)
        drawn = _drawn.get(os.fspath(bag), [])
    if made is None:
        from projection_server.workers.run import translate_bag

        made = translate_bag(bag)
    if drawn:   # what its world drew: the worker knows nothing of beliefs
        made = {**made, 'quantities': [*made['quantities'], *(
            ['sampled', [entity, key], value] for entity, key, value in drawn)]}
    return made


def submit(scenario: dict[str, Any], program: str, params: dict[str, Any],
           timeout: float, owner: str | None = None,
           physics: Mapping[str, Any] | None = None,
           plan: list[Any] | None = None,
           world: Sequence[int] | None = None) -> Future[ProjectionResult]:
    """Like :func:`project`, but return at once with a future of the result.

    For running a query's parametrizations ahead of Prolog's backtracking; a later
    :func:`project` of the same projection waits for the same future.
    """
    job = Job.checked(_world(scenario, world)[0], program, params, physics, plan)
    return _get_backend().submit(job, timeout, owner)


def prefetch(scenario: dict[str, Any], program: str, params_list: list[dict[str, Any]],
             timeout: float, owner: str | None = None,
             physics: Mapping[str, Any] | None = None,
             plan: list[Any] | None = None,
             worlds: list[Sequence[int] | None] | None = None) -> int:
    """Queue projections that a query will probably ask for next, all at once; return how
    many.

    Lets the workers run a query's next parametrizations while Prolog is still
    evaluating the current one. Invalid ones are skipped here: :func:`project`
    reports their errors when (and if) they are asked for.
    """
    jobs = []
    settings = _get_backend().settings
    for params, world in zip(params_list, worlds or [None] * len(params_list)):
        try:
            job = Job.checked(_world(scenario, world)[0], program, params, physics, plan)
            job.check_engine(settings)
            jobs.append(job)
        except ProjectionError:
            pass
    if jobs:
        _get_backend().submit_all(jobs, timeout, owner)
    return len(jobs)


def belief_problem(cls: str, key: str, belief: dict[str, Any]) -> str | None:
    """What is wrong with the distribution ``belief`` as property ``key`` of class ``cls``
    (:func:`projection_server.beliefs.problem`); None: nothing."""
    return beliefs.problem(cls, key, belief)


def vocabulary(scenario: dict[str, Any]) -> dict[str, Any]:
    """What any timeline of a projection of ``scenario`` (a description, its properties
    possibly distributions) can name (:func:`projection_server.timeline.vocabulary.vocabulary`
    of its nominal world): Prolog checks a query's conditions against it before projecting.

    Raises:
        ProjectionError: kind ``invalid_scenario`` for a description the simulator refuses.
    """
    from projection_server.timeline.vocabulary import vocabulary as of_scenario

    return of_scenario(parse_scenario(beliefs.nominal(scenario)))


def _world(scenario: dict[str, Any], world: Sequence[int] | None
           ) -> tuple[dict[str, Any], list[tuple[str, str, float]]]:
    """The plain world of ``scenario`` to project: nominal, or world ``[seed, index]``."""
    if world is None:
        return beliefs.nominal(scenario), []
    return beliefs.world(scenario, *world)


def plan_problem(plan: list[Any], params: dict[str, Any]) -> list[str] | None:
    """What is wrong with ``plan`` grounded with ``params``: None, or ``[kind, message]``
    with kind ``duration`` (its bound of simulated time is too long) or ``value``."""
    from projection_server.simulation.programs.plan import check_plan, PlanTooLong

    try:
        check_plan(plan, _programs.get('plan').check(params))
    except PlanTooLong as exc:
        return ['duration', exc.message]
    except ProjectionError as exc:
        return ['value', exc.message]
    return None


def prefetch_plan(program: str, params_list: list[dict[str, Any]], depth: int,
                  physics: Mapping[str, Any] | None = None) -> list[list[int]]:
    """Which of a query's parametrizations ``params_list`` (in the order it asks for them)
    to :func:`prefetch` when it comes to each: a list of indices per parametrization.

    When the query asks for parametrization ``i``, the families of the next ones, up to
    ``depth + 1`` families from ``i`` on, are queued, each family whole (the parametrizations
    that may share their first steps, :meth:`Job.family`; up to :data:`FAMILY_BATCH` at a
    time): a worker takes a family's projections together and steps what they share once.
    A parametrization of a program that shares nothing (on the engine of ``physics``, the
    query's physics options: :meth:`Job.family`) is a family of its own, so its query keeps
    ``depth`` projections queued ahead of the one it waits for.
    """
    try:
        shared = _programs.get(program)
    except ProjectionError:
        shared = None
    engine = (physics or {}).get('engine') or _config['engine'] or load_settings().physics.engine
    try:
        shares = shared is not None and shared.shares_steps(engine)
    except ProjectionError:   # an unknown engine: the projection reports it
        shares = False
    if not shares:
        count = len(params_list)
        return [list(range(min(count, depth + 1)))] * (count > 0) + [
            [i + depth] if i + depth < count else [] for i in range(1, count)]
    families: list[Any] = []
    sizes: dict[Any, int] = {}
    for index, params in enumerate(params_list):
        try:
            setup = shared.setup(shared.check(params))
        except ProjectionError:
            setup = None
        family = (index,) if setup is None else setup
        # A large family goes in batches, so a query never queues more than that at once.
        batch = sizes.get(family, 0)
        sizes[family] = batch + 1
        families.append((family, batch // FAMILY_BATCH))
    members: dict[Any, list[int]] = {}
    for index, family in enumerate(families):
        members.setdefault(family, []).append(index)
    queued: set[Any] = set()
    plan = []
    for index in range(len(families)):
        ahead: list[Any] = []
        for family in itertools.islice(families, index, None):
            if family not in ahead:
                ahead.append(family)
                if len(ahead) > depth:
                    break
        new = [family for family in ahead if family not in queued]
        queued.update(new)
        plan.append([i for family in new for i in members[family]])
    return plan


def cancel(owner: str) -> int:
    """Cancel the unfinished projections that only ``owner`` asked for; how many.

    ``owner``'s waits in :func:`project` and :func:`simulate` end at once with kind
    ``cancelled``, also for projections that run on because another owner wants them.
    """
    with _lock:
        backend = _backend
        _stops.setdefault(owner, threading.Event()).set()
    return backend.cancel(owner) if backend is not None else 0


def drop(owner: str) -> int:
    """Drop the queued projections that only ``owner`` asked for; how many.

    For a query that has ended: what it prefetched and no longer needs (a ONCE query after
    its solution, a closed INCREMENTAL one) leaves the workers to the next query. Running
    ones finish and keep their bags for whoever asks for them again.
    """
    with _lock:
        backend = _backend
    return backend.cancel(owner, running=False) if backend is not None else 0


def release(owner: str) -> None:
    """Forget ``owner`` once its query has ended."""
    with _lock:
        _stops.pop(owner, None)


def workers() -> int:
    """Number of simulation workers (the useful prefetch depth)."""
    return int(_config['workers'])


def programs() -> list[dict[str, Any]]:
    """The registered control programs with their formal parameters (name, unit, min, max,
    default)."""
    return _programs.describe()


def physics_settings(program: str | None = None,
                     engine: str | None = None) -> list[dict[str, Any]]:
    """The engine settings a query may choose, each with its name, unit, min, max, whether
    it is an integer, and its default for ``program`` (the settings file's without one) on
    ``engine`` (the node's default engine without one)."""
    return _get_backend().settings.describe_physics(program, engine)


def start() -> None:
    """Start the configured backend now rather than at the first projection (a Ray
    backend takes seconds to start or join its cluster).

    Raises:
        ProjectionError: kind ``invalid_settings`` or ``pool_closed`` if it cannot start.
    """
    _get_backend()


def shutdown() -> None:
    """Stop the process-wide backend (also done at exit)."""
    global _backend
    with _lock:
        old, _backend = _backend, None
    if old is not None:
        old.close()


def _wait(future: Future[ProjectionResult], owner: str | None = None) -> ProjectionResult:
    with _lock:
        stop = _stops.setdefault(owner, threading.Event()) if owner is not None else None
    while True:
        if stop is not None and stop.is_set():
            raise ProjectionError(ErrorKind.CANCELLED, 'the query waiting for it was cancelled')
        try:
            return future.result(timeout=_POLL if stop is None else 0.05)
        except TimeoutError:
            with _lock:
                if _backend is None:
                    raise ProjectionError(ErrorKind.POOL_CLOSED, 'the projection backend was closed')


def _get_backend() -> WorkerBackend:
    global _backend
    with _lock:
        if _backend is None:
            options = {'retention': _config['retention']}
            if _config['engine'] is not None:
                settings = load_settings()
                options['settings'] = dataclasses.replace(settings, physics=dataclasses.replace(
                    settings.physics, engine=_config['engine']))
            if _config['backend'] == 'ray' and _config['ray_address'] is not None:
                options['address'] = _config['ray_address']
            _backend = create_backend(_config['backend'],
                                      _config['bag_dir'] or default_bag_dir(),
                                      _config['workers'], **options)
        return _backend


atexit.register(shutdown)
