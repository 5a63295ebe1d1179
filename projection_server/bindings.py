"""Moved to :mod:`projection_server.client.bindings`; this re-export stays for one release."""

import warnings

from projection_server.client.bindings import *  # noqa: F401,F403
from projection_server.client.bindings import __all__  # noqa: F401

warnings.warn('projection_server.bindings is now projection_server.client.bindings',
              DeprecationWarning, stacklevel=2)
