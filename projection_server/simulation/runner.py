"""One projection, start to end, in the calling process: world, program, monitoring, bag.

Runs inside a pool worker (:mod:`projection_server.simulation.pool`); it is also callable
directly, e.g. from a debugger.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from projection_server.bags import BagWriter
from projection_server.simulation.job import canonical_json, code_version
from projection_server.simulation.monitor import Monitor
from projection_server.simulation.programs import get as get_program
from projection_server.simulation.scenario import parse_scenario
from projection_server.simulation.world import build_world

if TYPE_CHECKING:
    from pathlib import Path

    from projection_server.simulation.job import Job
    from projection_server.simulation.settings import Settings

__all__ = ['run_projection']


def run_projection(job: Job, settings: Settings, bag_path: Path) -> None:
    """Simulate ``job`` in a fresh DIRECT-mode world and log it into a new bag at ``bag_path``.

    The control program runs every ``steps_per_control`` physics steps and the monitor samples
    every ``steps_per_log`` steps, from the first step until the program's duration.
    """
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

    scenario = parse_scenario(job.scenario)
    program = get_program(job.program)
    key = job.key(settings)
    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        physics = build_world(client, scenario, settings)
        task = program.create(physics, scenario, dict(job.params),
                              np.random.default_rng(int(key[:16], 16)))
        rate = settings.physics.rate_hz
        control, log = settings.control.steps_per_control, settings.control.steps_per_log
        steps = math.ceil(task.duration * rate - 1e-9)
        with BagWriter(bag_path) as bag:
            monitor = Monitor(physics, bag)
            monitor.start({
                'job_key': key, 'scenario_name': scenario.name,
                'scenario_json': canonical_json(job.scenario), 'program': job.program,
                'parameters_json': canonical_json(job.params),
                'settings_json': canonical_json(settings.to_dict()),
                'code_version': code_version()})
            for step in range(steps):
                if step % control == 0:
                    task.control(physics)
                physics.step()
                if physics.step_count % log == 0:
                    monitor.sample()
    finally:
        client.disconnect()
