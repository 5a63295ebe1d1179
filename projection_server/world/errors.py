"""The one shape of what the robot's graph gave that cannot be used (a transform that
cannot be looked up, a description that cannot be read): a kind, what it is about, a
message; :mod:`.snapshot` turns each kind into the error a query answers with."""

from __future__ import annotations

__all__ = ['GraphError']


class GraphError(Exception):
    """:attr:`kind`, one of the subclass's kinds; :attr:`subject`, what it is about;
    :attr:`message`, the message that names it."""

    def __init__(self, kind: str, subject: str, message: str):
        super().__init__(message)
        self.kind, self.subject, self.message = kind, subject, message
