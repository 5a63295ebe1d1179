"""Table I's grasps and Table II's pours as trees of forked processes: how much of their
stepping their parametrizations share, and whether a forked continuation is exact.

Projections of one program, scenario and position make the same steps until their commands
first differ: pours until the smaller angle stops tilting or the shorter hold ends, grasps
until the fingers close with their force. Bare stepping of the knowledge base's scenario (the
program's control, step hooks, object models and end; no monitor, no log), each position's
parametrizations run twice:

* **straight**: each from the start, in its own task of a pool of 2 processes;
* **tree**: the steps they share once, then ``os.fork()`` where their commands part, each
  child continuing with its own parameters (the parent's PyBullet world is the child's,
  memory for memory), one tree per position in the same pool.

Prints the CPU seconds of both (a tree's summed over all its processes), their ratio, and
whether every leaf ended with the poses, velocities and joint states of every body, the
object models' state and the step count of its straight run, bit for bit::

    tools/with_env.sh python bench/prefix_sharing.py               # Table II's 27 pours
    tools/with_env.sh python bench/prefix_sharing.py --program grasp_object   # Table I
    tools/with_env.sh python bench/prefix_sharing.py --positions 0.0

With ``--pipeline`` both ways are whole projections: straight is
:meth:`~projection_server.simulation.runner.Simulator.run` (monitor, bag, timeline); in the
tree the monitor logs the shared steps once, and each child writes a bag of its own, its own
``/projection/info`` first and then the shared messages again, in the order they were
written. Every leaf's bag must then be byte for byte the straight run's, and its timeline
equal.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
import itertools
import math
import multiprocessing
import os
from pathlib import Path
import pickle
import platform
import resource
import sys
import tempfile
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))

from step_convergence import kb_scenario  # noqa: E402

SCENARIOS = {'pour': 'pouring', 'grasp_object': 'grasping'}
_state: dict = {}


def _start(program: str, pipeline: bool) -> None:
    import pybullet

    from projection_server.simulation.physics import bound_client
    from projection_server.simulation.runner import Simulator
    from projection_server.simulation.scenario import parse_scenario
    from projection_server.simulation.settings import load_settings

    _state['program'] = program
    _state['client'] = bound_client(pybullet.DIRECT)
    _state['description'] = kb_scenario(SCENARIOS[program])
    _state['scenario'] = parse_scenario(_state['description'])
    _state['base'] = load_settings()
    _state['settings'] = _state['base'].for_projection(program)
    if pipeline:
        _state['simulator'] = Simulator()


def _build(params: dict):
    import numpy as np

    from projection_server.simulation.programs import get as get_program
    from projection_server.simulation.world import build_world

    scenario, settings = _state['scenario'], _state['settings']
    physics = build_world(_state['client'], scenario, settings)
    task = get_program(_state['program']).create(physics, scenario, params,
                                                 np.random.default_rng(0))
    return physics, task


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    waited = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + waited.ru_utime + waited.ru_stime


def _advance(physics, task, until: int | None, monitor=None) -> None:
    """Step on to ``until`` (None: to the program's end: its duration, or the pour's rest),
    as :meth:`Simulator.run` does; with ``monitor``, sampling as it does."""
    control = physics.settings.control.steps_per_control
    log = physics.settings.control.steps_per_log
    if until is None:
        until = math.ceil(task.duration * physics.settings.physics.rate_hz - 1e-9)
        finished = getattr(task, 'finished', None)
    else:
        finished = None
    while physics.step_count < until:
        if physics.step_count % control == 0:
            task.control(physics)
        physics.step()
        if physics.step_count % log == 0:
            if monitor is not None:
                monitor.sample()
            if finished is not None and finished(physics):
                break


def _end_state(physics) -> tuple:
    c = physics.client
    bodies = []
    for body in physics.bodies.values():
        joints = range(c.getNumJoints(body.body_id))
        bodies.append((body.name, c.getBasePositionAndOrientation(body.body_id),
                       c.getBaseVelocity(body.body_id),
                       c.getJointStates(body.body_id, joints) if joints else ()))
    models = [(m.name, m.load, getattr(m, 'broken', None)) for m in physics.models]
    return physics.step_count, bodies, models


def straight(params: dict, pipeline: bool = False) -> tuple[dict, tuple, float]:
    start = _cpu()
    if pipeline:
        with tempfile.TemporaryDirectory() as tmp:
            bag = Path(tmp) / 'bag'
            end = _logged_end(bag, _state['simulator'].run(_job(params), _state['base'], bag))
        return params, end, _cpu() - start
    physics, task = _build(params)
    _advance(physics, task, None)
    return params, _end_state(physics), _cpu() - start


# --- whole projections: the monitor and a bag per leaf --------------------------------------
def _job(params: dict):
    from projection_server.simulation.job import Job

    return Job.checked(_state['description'], _state['program'], params)


def _logged_end(bag: Path, timeline: dict) -> tuple:
    """What a whole projection left: its bag's files and its timeline, but where they are
    (a bag directory named ``bag``, as its file names follow the directory's)."""
    meta = {k: v for k, v in timeline['meta'].items() if k != 'bag'}
    return ({f.name: f.read_bytes() for f in sorted(bag.iterdir())}, {**timeline, 'meta': meta})


class _Recorder:
    """A bag writer that also keeps every call, to be made again into a child's bag."""

    def __init__(self, writer, calls: list):
        self.writer, self.calls = writer, calls

    def write(self, topic: str, message, t_ns: int) -> None:
        self.calls.append(('write', (topic, message, t_ns)))
        self.writer.write(topic, message, t_ns)

    def write_sample(self, t_ns: int, messages) -> None:
        messages = list(messages)
        self.calls.append(('write_sample', (t_ns, messages)))
        self.writer.write_sample(t_ns, messages)

    def __getattr__(self, name: str):
        return getattr(self.writer, name)


def _info(params: dict) -> dict[str, str]:
    from projection_server.simulation.runner import projection_info

    return projection_info(_job(params), _state['base'], _state['scenario'].name)


def _rebag(monitor, params: dict, path: Path) -> None:
    """Give ``monitor`` a bag of its own at ``path``: ``params``' info, then what was
    written so far (the parent's bag file is left alone: children end with os._exit)."""
    from projection_server.bags import BagWriter, TOPICS
    from projection_server.simulation.monitor import Record

    shared = monitor.bag.calls
    writer = BagWriter(path).__enter__()
    info = writer.new('projection_interfaces/msg/ProjectionInfo',
                      header=shared[0][1][1].header, **_info(params))
    monitor.bag = _Recorder(writer, [])
    monitor.bag.write(TOPICS['info'], info, 0)
    for method, args in shared[1:]:
        getattr(monitor.bag, method)(*args)
    monitor.records[0] = Record('info', 0, info)


# --- where parametrizations part, per program ----------------------------------------------
def _retime(task, params: dict) -> None:
    """Give ``task`` the parameters of ``params`` that act after the world is set up (the
    position sets up the world: each position is a tree of its own)."""
    if _state['program'] == 'pour':
        from projection_server.simulation.programs.pour import AFTER, SETTLE, TILT_RATE

        task.angle, task.hold = params['angle'], params['time']
        task.tilted = SETTLE + task.angle / TILT_RATE
        task.released = task.tilted + task.hold
        task.upright = task.released + task.angle / TILT_RATE
        task.duration = task.upright + AFTER
    else:
        task.force = params['force']


def _recommand(task) -> None:
    """Issue again what the last step's hooks commanded for the next step (the pour's cup
    target follows its path after every step; the grasp commands only at control steps)."""
    if _state['program'] == 'pour':
        task._follow()


def _command(physics, task, params: dict, step: int):
    """What ``params`` has the program command for step ``step + 1``."""
    _retime(task, params)
    if _state['program'] == 'pour':
        return task.tilt(step / physics.settings.physics.rate_hz + task._lead)
    from projection_server.simulation.programs.grasp import APPROACHED

    if step % physics.settings.control.steps_per_control:
        return None
    # The fingers close, with the grip force, at the first control step from APPROACHED.
    return task.force if step / physics.settings.physics.rate_hz >= APPROACHED else None


def _name(params: dict) -> str:
    return '-'.join(f'{v}' for v in params.values())


def _tree(physics, task, leaves: list[dict], out: Path, monitor=None) -> None:
    """Run ``leaves`` (sharing the state and the next command) to their ends, forking
    where their commands part; each leaf's end state (with ``monitor``: its bag and
    timeline) goes to ``out``."""
    _retime(task, leaves[0])
    _recommand(task)
    if len(leaves) == 1:
        if monitor is None:
            _advance(physics, task, None)
            end = _end_state(physics)
        else:
            from projection_server.timeline.translate import translate_records

            bag = out / f'{_name(leaves[0])}.leaf' / 'bag'
            bag.parent.mkdir()
            _rebag(monitor, leaves[0], bag)
            _advance(physics, task, None, monitor)
            monitor.bag.writer.__exit__(None, None, None)
            end = _logged_end(bag, translate_records(monitor.records, bag))
        (out / _name(leaves[0])).write_bytes(pickle.dumps(end))
        return
    step = physics.step_count
    while len({_command(physics, task, p, step) for p in leaves}) == 1:
        step += 1
    _retime(task, leaves[0])
    _advance(physics, task, step, monitor)   # the steps these leaves share
    groups: dict = {}
    for p in leaves:
        groups.setdefault(_command(physics, task, p, step), []).append(p)
    for group in groups.values():
        pid = os.fork()
        if pid == 0:
            try:
                _tree(physics, task, group, out, monitor)
            finally:
                os._exit(0)
        os.waitpid(pid, 0)


def tree(leaves: list[dict], pipeline: bool = False) -> tuple[list[tuple[dict, tuple]], float]:
    start = _cpu()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        if pipeline:
            _tree_logged(leaves, out)
        else:
            physics, task = _build(leaves[0])
            _tree(physics, task, leaves, out)
        ends = [(p, pickle.loads((out / _name(p)).read_bytes())) for p in leaves]
    return ends, _cpu() - start


def _tree_logged(leaves: list[dict], out: Path) -> None:
    """The tree of whole projections, from a child (whose shared bag is never closed)."""
    from projection_server.bags import BagWriter
    from projection_server.simulation.monitor import Monitor

    pid = os.fork()
    if pid == 0:
        try:
            physics, task = _build(leaves[0])
            writer = BagWriter(out / 'shared.bag').__enter__()
            monitor = Monitor(physics, _Recorder(writer, []))
            monitor.start(_info(leaves[0]))
            _tree(physics, task, leaves, out, monitor)
        finally:
            os._exit(0)
    os.waitpid(pid, 0)


def main() -> int:
    from projection_server.reproduce import paper

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--program', choices=tuple(SCENARIOS), default='pour')
    parser.add_argument('--positions', type=float, nargs='*')
    parser.add_argument('--pipeline', action='store_true',
                        help='whole projections: monitor, a bag per leaf, timelines')
    args = parser.parse_args()
    if args.program == 'pour':
        positions = args.positions or paper.POUR_POSITIONS
        trees = [[{'angle': a, 'time': t, 'position': x}
                  for t, a in itertools.product(paper.POUR_TIMES, paper.POUR_ANGLES)]
                 for x in positions]
    else:
        positions = args.positions or paper.GRASP_POSITIONS
        trees = [[{'force': float(f), 'position': x} for f in paper.GRASP_FORCES]
                 for x in positions]
    with ProcessPoolExecutor(2, multiprocessing.get_context('forkserver'),
                             initializer=_start, initargs=(args.program, args.pipeline)) as pool:
        started = time.perf_counter()
        jobs = [p for leaves in trees for p in leaves]
        straights = list(pool.map(straight, jobs, [args.pipeline] * len(jobs)))
        straight_wall = time.perf_counter() - started
        started = time.perf_counter()
        forked = list(pool.map(tree, trees, [args.pipeline] * len(trees)))
        tree_wall = time.perf_counter() - started
    expected = {_name(p): end for p, end, _ in straights}
    same = sum(end == expected[_name(p)] for ends, _ in forked for p, end in ends)
    straight_cpu = sum(cpu for _, _, cpu in straights)
    tree_cpu = sum(cpu for _, cpu in forked)
    count = len(straights)
    what = ('whole projections (monitor, a bag each, timeline)' if args.pipeline
            else 'bare stepping with the object models')
    print(f'prefix sharing benchmark: {args.program} projections of one position stepped '
          'once where they agree, forked where their commands part, against each stepped '
          'from the start')
    print(f'  settings: {count} projections ({len(trees)} positions {list(positions)}, '
          f'{[{k: v for k, v in p.items() if k != "position"} for p in trees[0]]}), '
          f'{what} at the program\'s settings, 2 processes; '
          f'python {platform.python_version()}, {os.cpu_count()} cores, load average '
          f'{os.getloadavg()[0]:.1f} at the end')
    print(f'  straight: {straight_cpu:.1f} CPU s ({straight_wall:.1f} s wall)')
    print(f'  tree:     {tree_cpu:.1f} CPU s ({tree_wall:.1f} s wall), '
          f'{straight_cpu / tree_cpu:.2f}x less CPU')
    print(f'  leaves ending bit for bit as their straight run: {same}/{count}')
    return 0 if same == count else 1


if __name__ == '__main__':
    sys.exit(main())
