"""The ``local`` worker backend: supervised processes on this machine (the default)."""

from __future__ import annotations

from projection_server.workers.local.pool import WorkerPool

__all__ = ['WorkerPool']
