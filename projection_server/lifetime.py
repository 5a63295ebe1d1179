"""Processes that end with the process that started them, whatever ends it.

Linux's parent-death signal (``prctl(PR_SET_PDEATHSIG)``) is sent to a process when the
thread that started it ends: a SIGKILL of the parent included, which no handler of the
parent's can catch. It is not inherited by forked children, so each generation asks for
it: the node started by a script (:mod:`projection_server.client.launcher` names the
script's pid in :data:`PARENT_ENV`), the local pool's workers, the trees they fork and the
Ray actors' worker processes.
"""

from __future__ import annotations

import ctypes
import os
import signal

__all__ = ['PARENT_ENV', 'die_with_parent']

PARENT_ENV = 'PROJECTION_SERVER_PARENT'   # the launcher's pid, for the node it starts
_PR_SET_PDEATHSIG = 1


def die_with_parent(parent: int, sig: int = signal.SIGKILL) -> bool:
    """Have the calling process sent ``sig`` when its parent (the thread that started it)
    ends; False if the parent, pid ``parent``, has ended already."""
    try:
        ctypes.CDLL(None).prctl(_PR_SET_PDEATHSIG, int(sig))
    except (AttributeError, OSError):   # not Linux: it outlives a killed parent
        pass
    return os.getppid() == parent   # else the parent died before prctl
