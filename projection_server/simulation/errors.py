"""The one error class of the simulation subsystem."""

from __future__ import annotations

__all__ = ['ProjectionError']


class ProjectionError(Exception):
    """A projection could not be made; ``kind`` says why, for programs to dispatch on.

    Kinds: ``invalid_scenario``, ``invalid_parameters``, ``unknown_program``,
    ``invalid_settings``, ``timeout``, ``worker_crashed``, ``simulation_failed``,
    ``bag_error``, ``pool_closed``.
    """

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind
        self.message = message

    def __reduce__(self):
        # Pickled across the worker pipe: rebuild from (kind, message), not from args.
        return (type(self), (self.kind, self.message))

    def __str__(self) -> str:
        return f'{self.kind}: {self.message}'
