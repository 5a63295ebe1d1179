"""Robot models, registered by name: what a scenario's ``robot`` entity is built as.

* :mod:`.gantry`: ``pr2``, the PR2's gripper on a gantry (the paper's experiments), or on
  six joints for plans;
* :mod:`.urdf_arm`: ``urdf``, any URDF (or one-model SDF) arm with a gripper, given by a
  few facts; fingers on prismatic joints, or on revolute ones and linkages
  (:mod:`.linkage`).

What a plan drives is a :class:`~.manipulator.Manipulator` (:mod:`.manipulator`, with the
tool frame's conventions; :mod:`.kinematics` solves arms).

A model is added with :func:`register` (see :mod:`.gantry`); the ``robot`` object class
(:mod:`projection_server.simulation.objects.robot`) builds each robot entity with the model
its ``model`` property names.
"""

from __future__ import annotations

from projection_server.simulation.robots import gantry  # noqa: F401  (registers itself)
from projection_server.simulation.robots import urdf_arm  # noqa: F401  (registers itself)
from projection_server.simulation.robots.registry import (assets_dir, get, names, register,
                                                          RobotModel)

__all__ = ['RobotModel', 'assets_dir', 'get', 'names', 'register']
