"""Moved to :mod:`projection_server.client.launcher`; this re-export stays for one release."""

import warnings

from projection_server.client.launcher import *  # noqa: F401,F403
from projection_server.client.launcher import __all__  # noqa: F401

warnings.warn('projection_server.launcher is now projection_server.client.launcher',
              DeprecationWarning, stacklevel=2)
