"""Object classes, registered by name: what a scenario's entities may be.

Each class is one module (its property schema, builder and what the timeline needs of it),
registered with :func:`register` when imported, as dm_control's suite collects its domains:

* :mod:`.environment`, :mod:`.floor`, :mod:`.table`: the kitchen;
* :mod:`.robot`, :mod:`.gripper`: a robot and its gripper (built by a robot model,
  :mod:`projection_server.simulation.robots`);
* :mod:`.egg` (breakable), :mod:`.cup`, :mod:`.particle_fluid`, :mod:`.pancake_maker`,
  :mod:`.spatula`, :mod:`.pancake` (deformable): the paper's task objects;
* :mod:`.rigid_object`: a rigid body of any shape (a box, cylinder or sphere, a mesh, a
  URDF), breakable or not: everyday objects.

``assets/`` holds the package's own model files (the drinking glass): the first of the
asset directories model files resolve in (:mod:`projection_server.assets`).

Other installed packages add theirs through the entry-point group
``projection_server.objects`` (:mod:`projection_server.simulation.plugins`). Every class
must also be a class of the knowledge base (``prolog/kb/kitchen.ttl``, its
``simulatorClass`` and ``appliesTo``), which a test keeps equal to this registry.
"""

from __future__ import annotations

# The built-in classes (each registers itself).
from projection_server.simulation.objects import (cup, egg, environment, floor,  # noqa: F401
                                                  gripper, pancake, pancake_maker,
                                                  particle_fluid, rigid_object, robot,
                                                  spatula, table)
from projection_server.simulation.objects.registry import (describe, get, names, ObjectClass,
                                                           Property, register, REQUIRED)

__all__ = ['ObjectClass', 'Property', 'REQUIRED', 'describe', 'get', 'names', 'register']
