"""The robot's world as its ROS graph publishes it, and snapshots of it as scenarios.

* :mod:`.transforms`: a tf2-like buffer of ``/tf`` and ``/tf_static`` (pure);
* :mod:`.state`: the description, joint states and transforms last received (pure);
* :mod:`.description`: a URDF received as text, its meshes resolved, written as a file;
* :mod:`.snapshot`: what a scenario is made of, frozen at one time (pure);
* :mod:`.listener`: the node's subscriptions (ROS);
* :func:`try_snapshot`: what ``robot_world/2`` (``prolog/robot_world.pl``) calls.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any, TYPE_CHECKING

if TYPE_CHECKING:
    from projection_server.world.state import RobotWorld

# What robot_world/2 calls imports numpy only when there is a world to read: Prolog loads
# this module also where no simulator is installed (its own unit tests).
__all__ = ['bag_scenario', 'current', 'set_current', 'try_snapshot']

_lock = threading.Lock()
_current: RobotWorld | None = None

# The longest one call of try_snapshot() waits: Prolog calls it again until its own deadline,
# so that a query's time limit or cancel can stop it between calls.
WAIT_SLICE = 0.1


def set_current(world: RobotWorld | None) -> None:
    """Make ``world`` the one :func:`try_snapshot` reads (the node's; None: none)."""
    global _current
    with _lock:
        _current = world


def current() -> RobotWorld | None:
    with _lock:
        return _current


def try_snapshot(options: dict[str, Any], deadline: float) -> dict[str, Any]:
    """One try at a snapshot of the current world with ``options`` (``world_frame``,
    ``frames``, ``max_age``), waiting at most :data:`WAIT_SLICE` for what has not arrived.

    Returns ``{'status': 'ok', 'snapshot': ...}`` (:func:`.snapshot.take`),
    ``{'status': 'waiting'}`` while something is missing and ``deadline`` (``time.time()``)
    is not reached, else ``{'status': 'error', 'error': ...}`` (:class:`WorldError`).
    """
    world = current()
    if world is None:
        return {'status': 'error', 'error': {
            'formal': 'existence_error', 'type': 'robot_world', 'culprit': 'ros_graph',
            'message': 'this process reads no robot world: robot_world/2 runs in the '
                       'projection_server node (with its parameter robot_world true)'}}
    from projection_server.world.snapshot import NotYet, Options, take, WorldError

    opts = Options(world_frame=str(options.get('world_frame', 'map')).lstrip('/'),
                   frames=tuple(str(f).lstrip('/') for f in options.get('frames', ())),
                   max_age=float(options.get('max_age', 1.0)))
    try:
        return {'status': 'ok', 'snapshot': take(world, opts)}
    except NotYet as exc:
        left = deadline - time.time()
        if left <= 0:
            return {'status': 'error', 'error': exc.as_dict()}
        world.wait(min(WAIT_SLICE, left))
        return {'status': 'waiting'}
    except WorldError as exc:
        return {'status': 'error', 'error': exc.as_dict()}


def bag_scenario(bag: str) -> dict[str, Any]:
    """The scenario description a projection's bag was made from (its ``/projection/info``),
    for ``bag_scenario/2``.

    Raises:
        ProjectionError: kind ``bag_error`` for a bag without one.
    """
    from projection_server.bags.reader import read_bag
    from projection_server.errors import ErrorKind, ProjectionError

    for _, _, info in read_bag(bag, ['/projection/info']):
        return json.loads(info.scenario_json)
    raise ProjectionError(ErrorKind.BAG_ERROR, f'{bag} has no /projection/info')
