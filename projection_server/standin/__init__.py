"""The stand-in robot: a robot for the projection server to think for, in its own process.

Its own PyBullet world, finer than a projection's, with true object properties the server
is not told; ROS 2 topics as a real robot's (``/robot_description``, ``/joint_states``,
``/tf``, ``/tf_static``); plans executed as an action, and its world reset by a service
(:mod:`.node`, over the ROS-free :mod:`.world`).
"""

from __future__ import annotations

__all__: list[str] = []
