"""Simulation side of temporal projection: worlds, programs, monitoring.

Map of the package:

* :mod:`.runner`: one projection in the calling process (what a worker runs; the workers
  themselves are in :mod:`projection_server.workers`, which make its timeline).
* :mod:`.scenario`: the checked form of a scenario description.
* :mod:`.world`: the builder from a scenario to a PyBullet world; :mod:`.assets` its data.
* :mod:`.physics`: the world by entity names, the gripper, named queries.
* :mod:`.object_models` and :mod:`.contact_mechanics`: the breakable egg shell.
* :mod:`.programs`: robot control programs and their formal parameters.
* :mod:`.monitor`: the world's state as bag messages and records
  (:mod:`projection_server.bags`).
* :mod:`.job`: a projection and its cache key (its settings: :mod:`projection_server.settings`).
"""

from __future__ import annotations

from projection_server.errors import ProjectionError
from projection_server.settings import load_settings, Settings
from projection_server.simulation.job import Job

__all__ = ['Job', 'ProjectionError', 'Settings', 'load_settings']
