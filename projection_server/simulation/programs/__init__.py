"""Robot control programs, registered by name with their formal parameters.

A program is added with :func:`register` (see :mod:`.grasp` for the pattern; :mod:`.pour`
follows it, and so do :mod:`.turn` and :mod:`.wait`). Prolog reads :func:`describe`.
:mod:`.plan` is the program a query writes itself: a list of motion primitives.
"""

from __future__ import annotations

from projection_server.simulation.programs import grasp  # noqa: F401  (registers itself)
from projection_server.simulation.programs import plan  # noqa: F401  (registers itself)
from projection_server.simulation.programs import pour  # noqa: F401  (registers itself)
from projection_server.simulation.programs import turn  # noqa: F401  (registers itself)
from projection_server.simulation.programs import wait  # noqa: F401  (registers itself)
from projection_server.simulation.programs.registry import (
    describe,
    get,
    Parameter,
    Program,
    register,
    Task,
)

__all__ = ['Parameter', 'Program', 'Task', 'describe', 'get', 'register']
