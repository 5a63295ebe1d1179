"""What the benchmarks in bench/ share, over public surfaces of projection_server only.

* the command line and the settings line: :func:`arguments`, :func:`machine`,
  :func:`listed`;
* the knowledge base's scenarios, from the server's Prolog in this process, and their
  entities' properties: :func:`kb_scenario`, :func:`prolog`, :func:`find_entity`,
  :func:`set_properties`;
* a node of its own, a client of it and what its ping says: :func:`ros_domain`,
  :func:`start_node`, :func:`client`, :func:`node_with_client`, :class:`ServerStats`;
* what ``/proc`` says of a node and its projection workers: :func:`worker_pids`,
  :func:`wait_warm`, :func:`rss_mb`, :func:`cpu_seconds`;
* the floor a projection is measured against, the bare stepping of its world and program:
  :func:`bare_projection`, :func:`floor`, :func:`parallel_floor`.

A benchmark runs as ``tools/with_env.sh python bench/<name>.py``; Python puts bench/ on
``sys.path`` itself, so ``import harness`` needs nothing more::

    import harness

    harness.ros_domain(130)
    rclpy.init()
    with harness.start_node({'bag_dir': bags, 'projection_workers': 2}, log) as node, \\
            harness.client() as c:
        c.all(harness.TABLE_I)
        print(harness.rss_mb(node.proc.pid), [harness.rss_mb(p)
                                               for p in harness.worker_pids(node.proc.pid)])
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import functools
import json
import math
import os
from pathlib import Path
import platform
import statistics
import tempfile
import time
from typing import Any, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator, Mapping

    from projection_server.client import PrologClient
    from projection_server.client.launcher import NodeProcess
    from projection_server.settings import Settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Projection

# The paper's Table I (6 forces x 3 positions) as one query, with each grasp's outcome.
TABLE_I = ('make_projection(grasping, grasp_object, '
           '[(P, position, [-0.02, 0.00, 0.02]), (F, force, [1, 3, 5, 7, 9, 11])], TL), '
           '( occurs(break, _, TL) -> O = break ; occurs(slip, _, TL) -> O = slip ; O = ok )')


# --- command line and settings line -----------------------------------------------------
def arguments(doc: str, *, repeat: int | None = None,
              seed: int | None = None) -> argparse.ArgumentParser:
    """A parser described by ``doc``'s first line; with ``--repeat`` and ``--seed`` when
    they are given a default."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    if repeat is not None:
        parser.add_argument('--repeat', type=int, default=repeat,
                            help=f'rounds of the measurement (default {repeat})')
    if seed is not None:
        parser.add_argument('--seed', type=int, default=seed,
                            help=f'seed of the random choices (default {seed})')
    return parser


def machine() -> str:
    """Python's version, the cores and the load average now: every settings line's end."""
    return (f'python {platform.python_version()}, {os.cpu_count()} cores, '
            f'load average {os.getloadavg()[0]:.1f}')


def timed(c: PrologClient, bags: Path, text: str, *, once: bool = False,
          timeout: float = 900.0) -> tuple[float, int, Any]:
    """``text`` asked of client ``c`` (all solutions, or with ``once`` the first): its wall
    seconds, the bags it added to ``bags`` and its answer."""
    before = sum(1 for _ in bags.iterdir()) if bags.exists() else 0
    start = time.perf_counter()
    answer = (c.once(text, timeout=timeout) if once
              else c.all(text, timeout=timeout, max_solutions=10_000))
    elapsed = time.perf_counter() - start
    return elapsed, sum(1 for _ in bags.iterdir()) - before, answer


def medians(rows: Mapping[str, list[tuple[float, int]]]) -> None:
    """Print each query's median seconds and projections over its runs ``(seconds,
    projections)``, with the runs' seconds."""
    print(f'\n{"query":<12} {"median s":>9} {"projections":>12}   runs')
    for name, runs in rows.items():
        seconds = [s for s, _ in runs]
        print(f'{name:<12} {statistics.median(seconds):9.2f} '
              f'{statistics.median(n for _, n in runs):12.0f}   {listed(seconds)}')


def listed(values: Iterable[float], digits: int = 2) -> str:
    """``values`` as ``1.23, 4.56``: the runs behind a median."""
    return ', '.join(f'{v:.{digits}f}' for v in values)


# --- the knowledge base -----------------------------------------------------------------
@functools.cache
def prolog() -> Any:
    """janus with the server's Prolog loaded into this process (once)."""
    from projection_server.service import prolog_bridge

    prolog_bridge.load()
    import janus_swi

    return janus_swi


def kb_scenario(name: str) -> dict[str, Any]:
    """The knowledge base's scenario description ``name``, as ``simulate/5`` passes it to
    Python (a copy: the caller may change it)."""
    return copy.deepcopy(_scenario(name))


def find_entity(entities: list[dict[str, Any]], name: str) -> dict[str, Any]:
    """The entity ``name`` among a scenario description's ``entities`` and their parts."""
    for entity in entities:
        if entity['name'] == name:
            return entity
        found = find_entity(entity.get('parts', []), name)
        if found:
            return found
    return {}


def set_properties(entities: list[dict[str, Any]], changes: dict[str, Any],
                   default: str = 'pancake_mix1') -> None:
    """Set each ``ENTITY.NAME`` (or ``NAME``, a property of ``default``) of ``changes`` among
    a scenario description's ``entities``."""
    for key, value in changes.items():
        entity, _, prop = key.rpartition('.')
        find_entity(entities, entity or default)['properties'][prop] = value


def grasp_outcome(timeline: dict[str, Any], target: str = 'egg1') -> str:
    """A grasp's outcome off its timeline: ``break`` if ``target`` broke, else ``slip`` if
    it slipped, else ``ok``."""
    names = {event[0] for event in timeline['events'] if event[1] == [target]}
    return 'break' if 'break' in names else 'slip' if 'slip' in names else 'ok'


ERP_SETTINGS = ('erp', 'contact_erp', 'friction_erp')


def physics_setting(text: str) -> dict[str, Any]:
    """Physics settings from ``RATE/ITERATIONS[/ERP]`` (e.g. ``960/80/0.1``): ERP sets the
    error reduction of joints, contacts and friction (Bullet's fraction per step: ``0.2``
    at 480 Hz corrects as much a second as ``0.1`` at 960)."""
    rate, iterations, *erp = text.split('/')
    physics: dict[str, Any] = {'rate_hz': int(rate), 'solver_iterations': int(iterations)}
    if erp:
        physics.update(dict.fromkeys(ERP_SETTINGS, float(erp[0])))
    return physics


@functools.cache
def _scenario(name: str) -> dict[str, Any]:
    return prolog().query_once('scenario:scenario_description(S, D)', {'S': name})['D']


# --- a node and its client --------------------------------------------------------------
def ros_domain(base: int, span: int = 30) -> None:
    """A ROS domain of this run's own (``base`` + pid mod ``span``, unless one is set),
    discovery on loopback: a benchmark's node meets no one else's."""
    os.environ.setdefault('ROS_DOMAIN_ID', str(base + os.getpid() % span))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'


@contextlib.contextmanager
def start_node(params: Mapping[str, object], log: Path, *, node: str = '/projection_server',
               warm: bool = True, stop_timeout: float = 15.0) -> Iterator[NodeProcess]:
    """A projection_server ``node`` with ``params`` in its own process (rclpy must be
    initialised), its output in ``log``; yielded once its query service answers and, with
    ``warm``, once its ``projection_workers`` (local backend) have started and warmed up.
    Stopped on exit."""
    from projection_server.client.launcher import node_command, NodeProcess

    with NodeProcess(node_command(node, params), log, stop_timeout=stop_timeout) as proc:
        proc.wait_for_service(f'{node.rstrip("/")}/query')
        if warm:
            wait_warm(proc.proc.pid, int(params.get('projection_workers', 1)))
        yield proc


def client(server: str = '/projection_server', service_timeout: float = 60.0
           ) -> PrologClient:
    """A :class:`~projection_server.client.PrologClient` of ``server``, its services up."""
    from projection_server.client import PrologClient

    c = PrologClient(server, service_timeout=service_timeout)
    if not c.wait_for_server(service_timeout):
        c.close(finish=False)
        raise RuntimeError(f'{server} did not come up')
    return c


@contextlib.contextmanager
def node_with_client(workers: int = 2) -> Iterator[tuple[PrologClient, Path]]:
    """A node of ``workers`` projection workers (rclpy must be initialised), with an empty
    bag directory of its own and no bound on its bags, and a client of it: yields
    ``(client, bag directory)``; the node stopped and the directory removed on exit."""
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        bags = tmp / 'bags'
        with start_node({'bag_dir': str(bags), 'projection_workers': workers,
                         'max_bags': 10_000_000}, tmp / 'node.log'), client() as c:
            yield c, bags


class ServerStats:
    """What ``server``'s ``~/ping`` says (its pid, resident memory, live queries and
    engines), asked from a node of this process (rclpy must be initialised).

    >>> with ServerStats() as stats:
    ...     stats()['engines']
    """

    def __init__(self, server: str = '/projection_server'):
        import rclpy
        from std_srvs.srv import Trigger

        self._rclpy = rclpy
        self._node = rclpy.create_node(f'bench_stats_{os.getpid()}')
        self._ping = self._node.create_client(Trigger, f'{server.rstrip("/")}/ping')
        self._request = Trigger.Request()

    def __enter__(self) -> ServerStats:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __call__(self, timeout: float = 10.0) -> dict[str, Any] | None:
        """The ping's JSON; None if no answer came within ``timeout`` seconds."""
        if not self._ping.wait_for_service(timeout_sec=timeout):
            return None
        future = self._ping.call_async(self._request)
        self._rclpy.spin_until_future_complete(self._node, future, timeout_sec=timeout)
        return json.loads(future.result().message) if future.done() else None

    def close(self) -> None:
        self._node.destroy_node()


# --- /proc ------------------------------------------------------------------------------
def rss_mb(pid: int) -> float:
    """Resident set size of a process [MB] (0 if it is gone)."""
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def cpu_seconds(pid: int) -> float:
    """User and system CPU time of a process, all its threads [s] (0 if it is gone)."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _children(pid: int) -> list[int]:
    out = []
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / 'stat').read_text()
            except OSError:
                continue
            if int(stat.rsplit(')', 1)[1].split()[1]) == pid:
                out.append(int(entry.name))
    return out


def worker_pids(pid: int) -> list[int]:
    """The projection workers of the local backend in process ``pid`` (a node, or this
    process): the children of its multiprocessing forkserver."""
    out = []
    for child in _children(pid):
        try:
            cmdline = Path(f'/proc/{child}/cmdline').read_bytes()
        except OSError:
            continue
        if b'forkserver' in cmdline:
            out += _children(child)
    return out


def wait_warm(pid: int, workers: int, timeout: float = 120.0) -> None:
    """Until process ``pid`` has ``workers`` projection workers and none of them uses CPU
    any more (each has warmed up and waits for a job): what a node that has been up for a
    while offers its first query."""
    deadline = time.monotonic() + timeout
    last: dict[int, float] = {}
    while time.monotonic() < deadline:
        pids = worker_pids(pid)
        now = {p: cpu_seconds(p) for p in pids}
        if len(pids) == workers and now == last:
            return
        last = now
        time.sleep(0.25)
    raise RuntimeError(f'the workers of process {pid} did not settle within {timeout:g} s')


# --- the floor: bare stepping -----------------------------------------------------------
class _Discarded:
    """Takes a monitor's messages like a :class:`~projection_server.bags.BagWriter` and
    writes nothing."""

    def __init__(self) -> None:
        from projection_server.bags import typestore

        self._types = typestore().types

    def new(self, msgtype: str, **fields: Any) -> Any:
        return self._types[msgtype](**fields)

    def write(self, topic: str, message: Any, t_ns: int) -> None:
        pass

    def write_sample(self, t_ns: int, messages: Any) -> None:
        pass

    def write_samples(self, samples: Any) -> None:
        pass


def bare_projection(client: Any, job: Job, settings: Settings) -> Projection:
    """``job``'s world and task in ``client`` as a projection builds them, at step 0, with
    its monitor detached: stepping it (``projection.physics.step()`` and the task's
    ``control``) logs nothing and sums no contacts. Not for ``advance``, which samples."""
    from projection_server.simulation.runner import Projection

    projection = Projection(client, job, settings, _Discarded())
    projection.physics.step_hooks.remove(projection.monitor.contacts.add_step)
    return projection


def floor(client: Any, job: Job, settings: Settings, models: bool = False,
          queries: bool = False) -> tuple[float, float, int]:
    """Bare stepping of ``job``'s world and program (world building, the program's
    per-step commands and its end included): (wall, CPU seconds of this process, physics
    steps). Each step is ``stepSimulation`` and, for each body with an object model (the
    egg), one contact query.

    With ``models``, each step also runs the object models (the egg's shell), still without
    monitoring or log. With ``queries``, the engine queries that the log and the object
    models need are made and nothing is done with their answers beyond telling which pad
    touches the egg: each step the contact points of every moving body and, where the egg
    is touched, its pose and the states of the touching gripper's pad links; each sample
    the poses of the moving bodies and particles, their links' states, the grippers' joints
    and the contact points of every body."""
    start, cpu = time.perf_counter(), time.process_time()
    projection = bare_projection(client, job, settings)
    physics, task = projection.physics, projection.task
    settings = physics.settings   # the program's and the job's own, as a worker has them
    steps = math.ceil(task.duration * settings.physics.rate_hz - 1e-9)
    control, log = settings.control.steps_per_control, settings.control.steps_per_log
    modelled = [physics.body(model.name).body_id for model in physics.models]
    step_simulation, contact_points = client.stepSimulation, client.getContactPoints
    # The program's own per-step commands (the pour's cup on its path) and its end at rest
    # are the program: the floor runs them too. The monitor's hook is detached, so these
    # are all.
    hooks = list(physics.step_hooks)
    finished = getattr(task, 'finished', None)
    solid = [b for b in physics.bodies.values() if b.group is None]
    moving = [b.body_id for b in solid if not b.static]
    others = [body for body in moving if body not in modelled]
    named = [b.body_id for b in solid]
    linked = [(b.body_id, sorted(b.links)) for b in solid if not b.static and b.links]
    grippers = list(physics.grippers.values())
    # The egg's shell asks, in a step with contacts, for its own pose and, when a pad
    # touches it, for the states of that gripper's pad links (which pad touches is read
    # from the points: the least the shell must do with them).
    pad_links = {(g.body_id, pad.link): (g.body_id, tuple(p.link for p in g.pads))
                 for g in grippers for pad in g.pads}
    particles = [i for fluid in physics.fluids.values() for i in fluid.body_ids]
    base_pose, link_states = client.getBasePositionAndOrientation, client.getLinkStates
    for step in range(steps):
        if step % control == 0:
            task.control(physics)
        if models:
            physics.step()
        else:
            step_simulation()
            physics.step_count += 1
            if queries:
                touched = [contact_points(bodyA=body) for body in modelled]
            else:
                for body in modelled:
                    contact_points(bodyA=body)
            for hook in hooks:
                hook()
            if queries:
                for body, points in zip(modelled, touched):
                    if points:
                        base_pose(body)
                        for pad in {pad_links.get((p[2], p[4])) for p in points} - {None}:
                            link_states(pad[0], pad[1], computeForwardKinematics=True)
                for body in others:
                    contact_points(bodyA=body)
                if physics.step_count % log == 0:
                    for body in moving + particles:
                        base_pose(body)
                    for body, links in linked:
                        link_states(body, links, computeForwardKinematics=True)
                    for gripper in grippers:
                        gripper.state()
                    for body in named:
                        contact_points(bodyA=body)
        if finished is not None and physics.step_count % log == 0 and finished(physics):
            break
    return time.perf_counter() - start, time.process_time() - cpu, physics.step_count


_bare: dict[str, Any] = {}


def _bare_start() -> None:
    from projection_server.simulation.runner import Simulator

    _bare['simulator'] = Simulator()


def _bare_run(job: Job, settings: Settings) -> float:
    return floor(_bare['simulator'].client, job, settings)[0]


def parallel_floor(jobs: list[Job], settings: Settings, workers: int) -> float:
    """Wall time [s] of bare stepping ``jobs`` in ``workers`` processes at once (started and
    warmed up before the clock starts): the floor of that many workers on this machine now.
    """
    from concurrent.futures import ProcessPoolExecutor
    import multiprocessing

    with ProcessPoolExecutor(workers, multiprocessing.get_context('forkserver'),
                             initializer=_bare_start) as pool:
        list(pool.map(_bare_run, jobs[:workers], [settings] * workers))   # warm-up
        start = time.perf_counter()
        list(pool.map(_bare_run, jobs, [settings] * len(jobs)))
        return time.perf_counter() - start
