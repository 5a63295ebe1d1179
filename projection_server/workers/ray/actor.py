"""The Ray actor of the ``ray`` backend: one warm simulator in a Ray worker process.

ROS-free on purpose (no rclpy: it may run on any machine of a cluster). Like the ``local``
worker process it pays imports, the PyBullet connection, message type registration and a
throw-away projection (:mod:`projection_server.workers.warm_up`) once, runs each projection
in a fresh world and makes its timeline from the samples in memory. The bag is written
into a private temporary directory on the actor's machine (one left by an actor killed
meanwhile is deleted by the next projection there) and sent back as bytes, so the node's
bag directory needs no file system shared with the cluster. Every
method answers ``(result, ok)``; a failed projection's result is its
:class:`~projection_server.simulation.errors.ProjectionError`.
"""

from __future__ import annotations

import os
import shutil
import traceback
from typing import Any, TYPE_CHECKING

from projection_server.simulation.errors import ProjectionError
from projection_server.workers.bag_store import private_tmp_dir

if TYPE_CHECKING:
    from projection_server.simulation.job import Job

__all__ = ['ProjectionActor']


class ProjectionActor:
    """A warm PyBullet client that runs projections; made remote by the backend."""

    def __init__(self, settings: dict[str, Any]):
        # PyBullet's C code prints banners on stdout; errors travel back as results.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.close(devnull)
        self._error: ProjectionError | None = None
        self._simulator: Any = None
        self._warm_up: dict[str, Any] | None = None
        try:
            from projection_server.simulation.job import code_version
            from projection_server.simulation.runner import Simulator
            from projection_server.simulation.settings import Settings

            self._settings = Settings.from_dict(settings)
            self._code = code_version()
            self._simulator = Simulator()
        except Exception as exc:   # reported by ready(), like a local worker's start-up
            self._error = ProjectionError('simulation_failed', f'worker start-up: {exc}')
        else:
            from projection_server.workers.warm_up import warm_up

            self._warm_up = warm_up(self._simulator, self._settings)

    def ready(self) -> tuple[Any, bool]:
        """Where this actor runs and which code it has, or why it could not start."""
        if self._error is not None:
            return self._error, False
        import ray

        return {'pid': os.getpid(), 'node': ray.get_runtime_context().get_node_id(),
                'code_version': self._code, 'warm_up': self._warm_up}, True

    def project(self, job: Job, name: str) -> tuple[Any, bool]:
        """Run ``job`` into a bag called ``name``; ``({file: bytes}, timeline)`` of it."""
        if self._error is not None:
            return self._error, False
        tmp = private_tmp_dir('projection-ray-')
        try:
            bag = tmp / name
            timeline = self._simulator.run(job, self._settings, bag)
            files = {entry.name: entry.read_bytes() for entry in sorted(bag.iterdir())}
            return (files, timeline), True
        except ProjectionError as exc:
            return exc, False
        except Exception as exc:
            return ProjectionError(
                'simulation_failed',
                f'{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=8)}'), False
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
