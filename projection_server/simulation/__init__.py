"""Simulation side of temporal projection: workers, worlds, programs, monitoring.

Map of the package:

* :mod:`.runner`: one projection in the calling process (what a worker runs); the workers
  themselves are in :mod:`projection_server.workers`.
* :mod:`.scenario`: the checked form of a scenario description.
* :mod:`.world`: the builder from a scenario to a PyBullet world; :mod:`.assets` its data.
* :mod:`.physics`: the world by entity names, the gripper, named queries.
* :mod:`.object_models` and :mod:`.contact_mechanics`: the breakable egg shell.
* :mod:`.programs`: robot control programs and their formal parameters.
* :mod:`.monitor`: the world's state as bag messages (:mod:`projection_server.bags`).
* :mod:`.settings`: ``config/physics.yaml``; :mod:`.job`: a projection and its cache key.
"""

from __future__ import annotations

from projection_server.simulation.errors import ProjectionError
from projection_server.simulation.job import Job
from projection_server.simulation.settings import load_settings, Settings

__all__ = ['Job', 'ProjectionError', 'Settings', 'load_settings']
