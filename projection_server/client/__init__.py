"""Clients of a projection_server: the Python client and the ``prolog_query`` command.

    from projection_server.client import PrologClient
"""

from __future__ import annotations

from projection_server.client.prolog_client import (PrologClient, PrologClientError,
                                                    PrologDeadlineError, PrologQueryError,
                                                    PrologServerLost, server_hint)

__all__ = [
    'PrologClient',
    'PrologClientError',
    'PrologDeadlineError',
    'PrologQueryError',
    'PrologServerLost',
    'server_hint',
]
