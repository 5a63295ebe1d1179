"""The query service: the ROS node and everything between a request and Prolog.

Map of the package:

* :mod:`.node`: the ROS 2 node, parameters and services, nothing else.
* :mod:`.queries`: live queries, limits, time limits, reaping (no ROS).
* :mod:`.project_action`: the ``~/project`` action; :mod:`.progress`: each query's
  progress, one report per finished projection.
* :mod:`.prolog_bridge`: the one module that calls Prolog (janus).
"""

__all__: list[str] = []
