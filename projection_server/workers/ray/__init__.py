"""The ``ray`` worker backend: projection workers as Ray actors, on one machine or a cluster.

Importing this package imports Ray; the ``local`` backend never does.
"""

from __future__ import annotations

from projection_server.workers.ray.backend import connect, RayBackend

__all__ = ['RayBackend', 'connect']
