"""Moved to :mod:`projection_server.service.node`; this re-export stays for one release."""

import warnings

from projection_server.service.node import *  # noqa: F401,F403
from projection_server.service.node import __all__  # noqa: F401

warnings.warn('projection_server.node is now projection_server.service.node',
              DeprecationWarning, stacklevel=2)
