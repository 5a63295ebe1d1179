"""Canonical JSON: the text that cache keys and bags are made of."""

from __future__ import annotations

import json
from typing import Any

from projection_server.errors import ErrorKind, ProjectionError

__all__ = ['canonical_json']


def canonical_json(value: Any) -> str:
    """JSON with sorted keys and no whitespace: equal values give equal text.

    Raises:
        ProjectionError: kind ``invalid_scenario`` for a value that is not plain JSON data.
    """
    try:
        return json.dumps(value, sort_keys=True, separators=(',', ':'), allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'not plain JSON data: {exc}') from exc
