"""Object models: controllers that compute, in every physics step, what rigid bodies do not.

The paper (Kunze et al. 2011, sec. II) simulates breaking with "graph-based object models and
controllers that perform specialized computations in each simulation step". Here an object
model is any object with ``after_step(physics)`` and ``sample()``
(:class:`~projection_server.simulation.physics.ObjectModel`).
"""

from __future__ import annotations

from typing import Callable, TYPE_CHECKING

import numpy as np

from projection_server.simulation import contact_mechanics as cm

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics

__all__ = ['EggShell']


class EggShell:
    """A breakable egg shell: measures the load on its contacts and breaks above its limit.

    Each physics step, the contact points of the egg are grouped by the touching body and
    link, and each group's total normal force (Bullet's constraint solution) is turned into
    an *equivalent load* (:mod:`~projection_server.simulation.contact_mechanics`): the force
    that would give the same peak contact pressure when the egg is squeezed at its equator
    between flat faces, which is what ``breaking_force`` means. The egg breaks in the first
    step in which the largest equivalent load reaches ``breaking_force``.

    * A gripper pad's contact is solved as a rubber layer (the pad's stiffness) over the
      pad's real face. A pad centred on the egg touches its equator with its whole contact
      patch: the equivalent load is the grip force. A pad centred off the egg's middle along
      the long axis still touches the equator (its widest part) but near the pad's edge, so
      part of the patch is cut off and the peak pressure rises; the patch grows with the
      force, so the effect does too. This is why an egg grasped off-centre breaks at a lower
      grip force. When the egg slips and a pad slides over it, the pad's rounded rim rides on
      the shell and concentrates the load further (about 2 to 3 times the grip force).
    * Any other contact (table, floor, other objects) is a large flat face: the equivalent
      load is the normal force scaled by the shell's curvature at the contact point (an egg
      is weaker at its pointed ends).

    Whether the egg slips is left entirely to the rigid-body friction of the contacts.

    A broken egg is replaced by its remains (``replace(physics, name)``, supplied by the
    world builder) that the gripper no longer holds, and stays broken.
    """

    def __init__(self, name: str, semi_axes: tuple[float, float, float],
                 breaking_force: float | None,
                 replace: Callable[[Physics, str], None]):
        self.name = name
        self.semi_axes = semi_axes
        self.breaking_force = breaking_force
        self.broken = False
        self.load = 0.0           # equivalent load of the last step [N]
        self._peak = 0.0          # largest load since the last sample [N]
        self._replace = replace

    def after_step(self, physics: Physics) -> None:
        """Measure this step's load; break if it reaches the breaking force."""
        if self.broken:
            self.load = 0.0
            return
        self.load = self._measure(physics)
        self._peak = max(self._peak, self.load)
        if self.breaking_force is not None and self.load >= self.breaking_force:
            self.broken = True
            self._replace(physics, self.name)

    def sample(self) -> tuple[float, float, bool]:
        """``(largest load since the last sample, breaking force or 0, broken)``."""
        peak, self._peak = self._peak, 0.0
        return peak, self.breaking_force or 0.0, self.broken

    def _measure(self, physics: Physics) -> float:
        c = physics.client
        body_id = physics.body(self.name).body_id
        points = c.getContactPoints(bodyA=body_id)
        if not points:
            return 0.0
        pos, orn = c.getBasePositionAndOrientation(body_id)
        pos = np.asarray(pos)
        rot = np.asarray(c.getMatrixFromQuaternion(orn)).reshape(3, 3)
        groups: dict[tuple[int, int], list[tuple[float, np.ndarray]]] = {}
        for point in points:
            groups.setdefault((point[2], point[4]), []).append((point[9], np.asarray(point[5])))
        grippers = {g.body_id: g for g in physics.grippers.values()}
        pads = {(body, face[0].link): face
                for body in {key[0] for key in groups} & grippers.keys()
                for face in grippers[body].pad_faces()}
        loads = []
        for key, group in groups.items():
            force = sum(f for f, _ in group)
            if force <= 0.0:
                continue
            face = pads.get(key)
            peak = None
            if face is not None:
                pad, centre, axes, normal = face
                peak = cm.pad_peak_pressure(force, self.semi_axes, rot, pos, centre, axes,
                                            normal, pad.half_extents, pad.stiffness,
                                            pad.rim_radius)
            if peak is not None:
                loads.append(cm.equivalent_load(peak, face[0].stiffness, self.semi_axes))
            else:
                where = sum(f * p for f, p in group) / force
                loads.append(cm.curvature_load(force, self.semi_axes, rot.T @ (where - pos)))
        return max(loads, default=0.0)
