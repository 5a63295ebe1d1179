"""Object models: controllers that compute, in every physics step, what rigid bodies do not.

The paper (Kunze et al. 2011, sec. II) simulates breaking with "graph-based object models and
controllers that perform specialized computations in each simulation step". Here an object
model is any object with ``after_step(physics)`` and ``sample()``
(:class:`~projection_server.simulation.physics.ObjectModel`).

Breaking is one criterion for every breakable object (:class:`Breakable`): the largest
*equivalent load* of its contacts in a step, averaged over :data:`BREAK_WINDOW`, reaches its
``breaking_force``. What differs is how a contact's load is found: an egg's shell
(:class:`EggShell`) weighs its curvature and the gripper pads' mechanics; a rigid object
(:class:`RigidBreakable`) meets the world with flat faces, so a contact's equivalent load is
its normal force.
"""

from __future__ import annotations

from collections import deque
import math
from typing import Any, Callable, TYPE_CHECKING

import numpy as np

from projection_server.simulation import contact_mechanics as cm

if TYPE_CHECKING:
    from projection_server.simulation.physics import Gripper, Pad, Physics

__all__ = ['BREAK_WINDOW', 'Breakable', 'EggShell', 'RigidBreakable']


BREAK_WINDOW = 1.0 / 60.0   # s over which a breakable object's load is averaged
CACHE_FORCE = 0.01          # relative change of a pad's force that re-solves its pressure
CACHE_SHIFT = 5.0e-5        # m the shell may move on a pad before its pressure is re-solved
CACHE_TURN = 2.0e-3         # rad it may turn


class Breakable:
    """What every breakable object shares: its load, the window it is averaged over, and
    breaking when the average reaches ``breaking_force`` (None: never).

    A subclass says what a step's load is (``_measure(physics)``: the largest equivalent
    load of the object's contacts [N]). The load is averaged over the last
    :data:`BREAK_WINDOW` of simulated time, and the object breaks in the first step in
    which the average reaches ``breaking_force``: a steady squeeze gives its force at any
    step size, and an impact its impulse over the window, where a single step's peak grows
    as the step shrinks. A broken object is handed to ``replace(physics, name)`` (its
    remains), and stays broken.
    """

    def __init__(self, name: str, breaking_force: float | None,
                 replace: Callable[[Physics, str], None]):
        self.name = name
        self.breaking_force = breaking_force
        self.broken = False
        self.load = 0.0           # the load (window average) after the last step [N]
        self._peak = 0.0          # largest load since the last sample [N]
        self._replace = replace
        self._window: deque[float] = deque()
        self._window_sum = 0.0
        self._window_steps = 1
        self._body_id = -1
        self._version = -1   # of the physics' bodies that the plan is of

    def after_step(self, physics: Physics) -> None:
        """Measure this step's load; break if the window's average reaches the limit."""
        if self.broken:
            self.load = 0.0
            return
        if self._version != physics.bodies_version:
            self._plan(physics)
        current = self._measure(physics)
        window = self._window
        window.append(current)
        self._window_sum += current
        if len(window) > self._window_steps:
            self._window_sum -= window.popleft()
        load = self._window_sum / self._window_steps
        # max(0.0, load) and max(peak, load), as comparisons
        self.load = load = load if load > 0.0 else 0.0
        if load > self._peak:
            self._peak = load
        if self.breaking_force is not None and load >= self.breaking_force:
            self.broken = True
            self._replace(physics, self.name)

    def sample(self) -> tuple[float, float, bool]:
        """``(largest load since the last sample, breaking force or 0, broken)``."""
        peak, self._peak = self._peak, 0.0
        return peak, self.breaking_force or 0.0, self.broken

    def _plan(self, physics: Physics) -> None:
        """What the step needs of the world as it is now (once per change of its bodies)."""
        self._body_id = physics.body(self.name).body_id
        self._window_steps = max(1, round(BREAK_WINDOW * physics.settings.physics.rate_hz))
        self._version = physics.bodies_version

    def _measure(self, physics: Physics) -> float:
        raise NotImplementedError


class RigidBreakable(Breakable):
    """A breakable rigid object (a glass, a plate): it meets the world with flat faces, so
    the equivalent load of a contact is its normal force. The contact points of the body
    (all its links) are grouped by the touching body and link; the step's load is the
    largest group's total normal force (Bullet's constraint solution)."""

    def _measure(self, physics: Physics) -> float:
        points = physics.contact_points(self._body_id)
        if not points:
            return 0.0
        groups: dict[tuple[int, int], float] = {}
        for point in points:
            key = (point[2], point[4])
            groups[key] = groups.get(key, 0.0) + point[9]
        largest = max(groups.values())
        return largest if largest > 0.0 else 0.0


class EggShell(Breakable):
    """A breakable egg shell: measures the load on its contacts and breaks above its limit.

    Each physics step, the contact points of the egg are grouped by the touching body and
    link, and each group's total normal force (Bullet's constraint solution) is turned into
    an *equivalent load* (:mod:`~projection_server.simulation.contact_mechanics`): the force
    that would give the same peak contact pressure when the egg is squeezed at its equator
    between flat faces, which is what ``breaking_force`` means. The shell breaks by the
    criterion of :class:`Breakable`.

    * A gripper pad's contact is solved as a rubber layer (the pad's stiffness) over the
      pad's real face. A pad centred on the egg touches its equator with its whole contact
      patch: the equivalent load is the grip force. A pad centred off the egg's middle along
      the long axis still touches the equator (its widest part) but near the pad's edge, so
      part of the patch is cut off and the peak pressure rises; the patch grows with the
      force, so the effect does too. This is why an egg grasped off-centre breaks at a lower
      grip force. When the egg slips and a pad slides over it, the pad's rounded rim rides on
      the shell and concentrates the load further (about 2 to 3 times the grip force).
      The pad's solution is kept while the pad's force changes by less than
      :data:`CACHE_FORCE` and the shell moves on the pad by less than :data:`CACHE_SHIFT`
      and :data:`CACHE_TURN` (the load is scaled with the force meanwhile): within the
      model's own discretisation error, at a fraction of the cost of a physics step.
    * Any other contact (table, floor, other objects) is a large flat face: the equivalent
      load is the normal force scaled by the shell's curvature at the contact point (an egg
      is weaker at its pointed ends).

    Whether the egg slips is left entirely to the rigid-body friction of the contacts.

    A broken egg is replaced by its remains (``replace(physics, name)``, supplied by the
    world builder) that the gripper no longer holds, and stays broken.
    """

    def __init__(self, name: str, semi_axes: tuple[float, float, float],
                 breaking_force: float | None,
                 replace: Callable[[Physics, str], None], cache: bool = True):
        super().__init__(name, breaking_force, replace)
        self.semi_axes = semi_axes
        self.cache = cache   # solve the pads anew each step when False (for measuring)
        # (body, link) of a pad -> (force, shell pose in the face's frame, load) of its
        # last solution
        self._cache: dict[tuple[int, int], tuple[float, tuple[float, ...], Quat, float]] = {}
        self._pads: dict[tuple[int, int], tuple[Gripper, Pad]] = {}
        self._pad_links: dict[int, list[int]] = {}   # gripper body -> its pads' links

    def _plan(self, physics: Physics) -> None:
        super()._plan(physics)
        self._pads = {(g.body_id, pad.link): (g, pad)
                      for g in physics.grippers.values() for pad in g.pads}
        # A gripper's pad links, asked for in one query when any of its pads is touched.
        self._pad_links = {g.body_id: [pad.link for pad in g.pads]
                           for g in physics.grippers.values()}

    def _measure(self, physics: Physics) -> float:
        body_id = self._body_id
        points = physics.contact_points(body_id)
        if not points:
            if self._cache:
                self._cache.clear()
            return 0.0
        # Plain floats: a step's handful of contacts costs less than numpy's overhead.
        groups: dict[tuple[int, int], list[float]] = {}
        for point in points:
            f, (x, y, z) = point[9], point[5]
            group = groups.get((point[2], point[4]))
            if group is None:
                groups[(point[2], point[4])] = [f, f * x, f * y, f * z]
            else:
                group[0] += f
                group[1] += f * x
                group[2] += f * y
                group[3] += f * z
        cache = self._cache
        if cache:
            for key in [k for k in cache if k not in groups]:
                del cache[key]
        pos, orn = physics.base_pose(body_id)
        pads, states = self._pads, None
        largest = 0.0   # max(loads, default=0.0); the loads are not negative
        for key, (force, fx, fy, fz) in groups.items():
            if force <= 0.0:
                continue
            pad = pads.get(key)
            load = None
            if pad is not None:
                if states is None:
                    links = self._pad_links[key[0]]
                    states = dict(zip(links, physics.link_poses(key[0], links)))
                load = self._pad_load(physics, key, pad[1], states[key[1]], force, pos, orn)
            if load is None:
                where = (fx / force - pos[0], fy / force - pos[1], fz / force - pos[2])
                load = cm.curvature_load(force, self.semi_axes, _rotate(_conjugate(orn), where))
            if load > largest:
                largest = load
        return largest

    def _pad_load(self, physics: Physics, key: tuple[int, int], pad: Pad, state: Any,
                  force: float, pos: tuple[float, float, float],
                  orn: tuple[float, float, float, float]) -> float | None:
        """Equivalent load of a pad's contact (``state``: the pad link's world frame);
        None if the pad is not over the shell."""
        # _rotate(inverse, pos - origin) and _multiply(inverse, orn) of the link's
        # conjugate, written out (every step a pad touches): the same operations.
        (px, py, pz), (qx, qy, qz) = pos, state[0]
        sx, sy, sz, sw = state[1]
        ax, ay, az, aw = -sx, -sy, -sz, sw
        bx, by, bz = px - qx, py - qy, pz - qz
        mx = aw * bx + ax * 0.0 + ay * bz - az * by
        my = aw * by - ax * bz + ay * 0.0 + az * bx
        mz = aw * bz + ax * by - ay * bx + az * 0.0
        mw = aw * 0.0 - ax * bx - ay * by - az * bz
        cx, cy, cz, cw = -ax, -ay, -az, aw
        offset = (mw * cx + mx * cw + my * cz - mz * cy, mw * cy - mx * cz + my * cw + mz * cx,
                  mw * cz + mx * cy - my * cx + mz * cw)
        bx, by, bz, bw = orn
        turn = (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)
        cached = self._cache.get(key)
        if cached is not None and self.cache:
            force0, (ox, oy, oz), turn0, load0 = cached
            if abs(force - force0) <= CACHE_FORCE * force0:
                dx, dy, dz = abs(offset[0] - ox), abs(offset[1] - oy), abs(offset[2] - oz)
                shift = dx if dx >= dy and dx >= dz else dy if dy >= dz else dz   # max()
                if shift <= CACHE_SHIFT:
                    dot = abs(turn[0] * turn0[0] + turn[1] * turn0[1] + turn[2] * turn0[2]
                              + turn[3] * turn0[3])
                    if 2.0 * math.acos(dot if dot < 1.0 else 1.0) <= CACHE_TURN:
                        return load0 * force / force0
        origin = np.asarray(state[0])
        rot = physics.rotation_matrix(state[1])
        shell = physics.rotation_matrix(orn)
        peak = cm.pad_peak_pressure(force, self.semi_axes, shell, np.asarray(pos),
                                    origin + rot @ pad.centre, (rot @ np.asarray(pad.axes).T).T,
                                    rot @ pad.normal, pad.half_extents, pad.stiffness,
                                    pad.rim_radius)
        if peak is None:
            self._cache.pop(key, None)
            return None
        load = cm.equivalent_load(peak, pad.stiffness, self.semi_axes)
        self._cache[key] = (force, offset, turn, load)
        return load


Quat = tuple[float, float, float, float]


def _conjugate(q: Quat) -> Quat:
    return (-q[0], -q[1], -q[2], q[3])


def _multiply(a: Quat, b: Quat) -> Quat:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def _rotate(q: Quat, v: tuple[float, float, float]) -> tuple[float, float, float]:
    """``q * (v, 0) * conj(q)``, written out: :func:`_multiply` twice, term for term."""
    ax, ay, az, aw = q
    bx, by, bz = v
    bw = 0.0
    mx = aw * bx + ax * bw + ay * bz - az * by
    my = aw * by - ax * bz + ay * bw + az * bx
    mz = aw * bz + ax * by - ay * bx + az * bw
    mw = aw * bw - ax * bx - ay * by - az * bz
    cx, cy, cz, cw = -ax, -ay, -az, aw
    return (mw * cx + mx * cw + my * cz - mz * cy, mw * cy - mx * cz + my * cw + mz * cx,
            mw * cz + mx * cy - my * cx + mz * cw)


def _angle(a: Quat, b: Quat) -> float:
    """Angle [rad] of the rotation between two unit quaternions."""
    dot = abs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3])
    return 2.0 * math.acos(min(1.0, dot))
