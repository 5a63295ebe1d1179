"""The error of the projection side, which every stage may raise: one class, one set of
kinds.

A :class:`ProjectionError` crosses process boundaries (a worker's pipe, Ray's object
store) and reaches Prolog as ``error(projection_error(Kind, Message), _)``; its
:class:`ErrorKind` is what programs dispatch on.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ['ErrorKind', 'ProjectionError']


class ErrorKind(StrEnum):
    """Why a projection could not be made (the ``Kind`` of Prolog's
    ``projection_error(Kind, Message)``)."""

    INVALID_SCENARIO = 'invalid_scenario'      # the scenario description is refused
    INVALID_PARAMETERS = 'invalid_parameters'  # a program's parameters or a time limit
    UNKNOWN_PROGRAM = 'unknown_program'        # no program of that name
    INVALID_SETTINGS = 'invalid_settings'      # physics settings, backend options, code version
    UNREACHABLE = 'unreachable'                # a robot cannot reach a pose it is sent to
    PLAN_DURATION = 'plan_duration'            # a plan cannot finish in its simulated time
    TIMEOUT = 'timeout'                        # the projection ran over its time limit
    CANCELLED = 'cancelled'                    # the query that wanted it was cancelled
    WORKER_CRASHED = 'worker_crashed'          # the worker process died under it
    SIMULATION_FAILED = 'simulation_failed'    # the simulation raised
    BAG_ERROR = 'bag_error'                    # a bag cannot be written or read
    POOL_CLOSED = 'pool_closed'                # the backend is closed or cannot start


class ProjectionError(Exception):
    """A projection could not be made; :attr:`kind` (an :class:`ErrorKind`) says why.

    ``kind`` may be given as the kind's name (``'timeout'``); an unknown one is a bug and
    raises ValueError.
    """

    def __init__(self, kind: ErrorKind | str, message: str):
        super().__init__(message)
        self.kind = ErrorKind(kind)
        self.message = message

    def __reduce__(self):
        # Pickled across the worker pipe: rebuild from (kind, message), not from args.
        return (type(self), (str(self.kind), self.message))

    def __str__(self) -> str:
        return f'{self.kind}: {self.message}'
