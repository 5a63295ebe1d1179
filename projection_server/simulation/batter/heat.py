"""Heat in a batter, and the pancake that sets from it: a step hook per fluid.

Every particle has a temperature ``T`` [deg C]. After every physics step of ``dt``:

* **Pan.** A particle that touches the top of a heated pancake maker (its centre over the
  pan's disc, within its radius, and at most ``(1 +`` :data:`TOUCH_TOLERANCE` ``) R`` above
  its top: geometry of the disc, no contact query) moves towards the pan's surface
  temperature ``T_pan`` at the rate ``pan_heat_rate`` ``k_p`` [1/s] (Newton's law of
  heating), integrated exactly over the step: ``T += (T_pan - T) (1 - exp(-k_p dt))``.
* **Conduction.** Two particles that touch (centres closer than ``2 R (1 +``
  :data:`TOUCH_TOLERANCE` ``)``, from a Verlet list of the positions read once per step)
  relax towards each other at the rate ``conduction_rate`` ``k_c`` [1/s]: each pair
  exchanges ``a (T_j - T_i)`` with ``a = (1 - exp(-2 k_c dt)) / 2`` (an isolated pair's
  difference then decays exactly as ``exp(-2 k_c t)``), all pairs at once from the
  temperatures before the exchange. ``a`` is capped at ``1 /`` :data:`~.forces.KISSING`, so each new
  temperature is a weighted mean of old ones (no particle overshoots, whatever the step);
  heat is conserved.
* **Air** (optional, ``air_cooling_rate`` ``k_a`` [1/s]): every particle moves towards
  :data:`AIR_TEMPERATURE` at ``k_a``, exactly as on the pan.

The three are applied one after the other in each step (operator splitting): each is exact
or a convex mean, so the integration is stable for any step and converges as ``dt -> 0``.

**Setting.** A particle whose temperature has reached ``setting_temperature`` is set, and
stays set (egg and starch set irreversibly at 60-70 deg C; iGibson 2.0 calls an object
cooked at 70 deg C). A set particle takes the friction of a cooked crust, ``set_friction``
(if given): wet batter slides where a crust grips. And it loses its rolling and spinning
friction: those stand for a wet blob's resistance to rolling (what holds a heap of batter
up), while a set particle is a bead of a solid whose turning its bonds hold. Kept, they
lock each bead's turning at its contacts against the bonds pinned to its surface, and the
bonded net shakes itself apart at rest (a cooked batter of 153 particles on the pan: its
fastest particle at 0.5 m/s and 98 bonds broken after 1 s at 960 Hz, 24 mm/s and none
yet at 240 Hz, the sooner the finer the step). Two set particles that touch bond once:
a ``JOINT_POINT2POINT`` constraint between the two bodies, its pivot where they touch (the
midpoint of their centres, fixed in each body's frame), whose force is limited to
``bond_strength`` [N]. A point-to-point bond holds the two centres together but lets each
sphere turn (three constraint rows, not a fixed joint's six); a triangulated net of them is
stiff in its plane and bends out of it, like a pancake. A bond pulled harder than its
strength yields, and the pair drifts apart; the bond breaks (its constraint is removed)
when the gap between the two spheres exceeds :data:`BREAK_GAP` ``R``: so a bond breaks
past a force. A pair bonds at most once (a broken bond does not re-form).

The state (temperatures, set flags and the bonds in force) is reported by
:meth:`BatterHeat.thermal_state` and logged every monitoring sample
(:mod:`projection_server.simulation.monitor`). A projection can start from a batter's state
at the end of another (the fluid's ``positions``, ``temperatures`` and ``bonds``): the bonds
are made again when the world is built.

Cost per step: one read of the positions (shared with the batter's forces and the monitor,
:meth:`Physics.particle_state`), numpy over the touching pairs (drawn from the Verlet list
that the batter's forces use, :func:`~.neighbours.fluid_neighbour_list`), and PyBullet calls
only for bonds that form or break.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, TYPE_CHECKING

import numpy as np

from projection_server.simulation.batter.forces import KISSING
from projection_server.simulation.batter.neighbours import fluid_neighbour_list

if TYPE_CHECKING:
    from collections.abc import Sequence

    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Scenario

__all__ = ['ABSOLUTE_ZERO', 'AIR_TEMPERATURE', 'BREAK_GAP', 'BatterHeat', 'HeatSource',
           'TOUCH_TOLERANCE', 'ThermalState', 'unreachable_setting']

TOUCH_TOLERANCE = 0.05   # touching: a gap of up to this many particle radii
BREAK_GAP = 0.5          # a bond breaks at a gap of this many particle radii
AIR_TEMPERATURE = 20.0   # deg C of the kitchen's air
ABSOLUTE_ZERO = -273.15  # deg C


def unreachable_setting(scenario: Scenario) -> list[str]:
    """Why nothing of a batter of ``scenario`` will set, for each batter that none of
    its pancake makers can heat to its setting temperature (none: [])."""
    pans = [e for e in scenario.entities if 'heating' in e.properties]
    if not pans:
        return []
    hottest = max(max(e.properties['temperature'] for e in pans if e.properties['heating'])
                  if any(e.properties['heating'] for e in pans) else AIR_TEMPERATURE,
                  AIR_TEMPERATURE)
    out = []
    for fluid in scenario.entities:
        p = fluid.properties
        if 'setting_temperature' not in p:
            continue
        warmest = max([hottest, p['temperature'], *(p.get('temperatures') or ())])
        if p['setting_temperature'] > warmest:
            out.append(f'{fluid.name}: its setting_temperature, {p["setting_temperature"]} '
                       f'deg C, is above the {warmest} deg C that its pancake makers and '
                       'its own temperature reach: nothing of it will set')
    return out


class HeatSource(NamedTuple):
    """The heated top of a pancake maker: a horizontal disc (centre (x, y), top z, radius
    [m]) at ``temperature`` [deg C]."""

    centre: tuple[float, float]
    top: float
    radius: float
    temperature: float


class ThermalState(NamedTuple):
    """A fluid's thermal state at one time: temperatures [deg C] (n,), set flags (n,) and the
    bonds in force (m, 2) as particle index pairs ``i < j``."""

    fluid: str
    temperatures: np.ndarray
    set: np.ndarray
    bonds: np.ndarray


class BatterHeat:
    """Heat, setting and bonds of fluid ``name`` of ``physics`` (``radius`` [m] of each
    particle); call it after every physics step.

    ``sources`` are the heated pans, ``temperatures`` the particles' initial temperatures
    [deg C], ``bonds`` pairs bonded at the start (made now). A particle that sets takes
    ``set_friction`` and, if given, the rotational inertia ``set_inertia`` [kg m^2]."""

    def __init__(self, physics: Physics, name: str, radius: float,
                 sources: Sequence[HeatSource], temperatures: np.ndarray,
                 setting_temperature: float, pan_heat_rate: float, conduction_rate: float,
                 air_cooling_rate: float, bond_strength: float,
                 bonds: Sequence[Sequence[int]] = (), set_friction: float | None = None,
                 set_inertia: float | None = None):
        self._physics = physics
        self.name = name
        self._ids = physics.fluids[name].body_ids
        n = len(self._ids)
        self._radius = radius
        self._sources = tuple(sources)
        self.temperature = np.array(temperatures, dtype=float).reshape(n)
        self._setting = setting_temperature
        self.set = self.temperature >= setting_temperature
        self._set_friction = set_friction
        self._set_inertia = set_inertia
        dt = 1.0 / physics.settings.physics.rate_hz
        self._pan = -math.expm1(-pan_heat_rate * dt)
        self._air = -math.expm1(-air_cooling_rate * dt)
        self._exchange = min(-math.expm1(-2.0 * conduction_rate * dt) / 2.0, 1.0 / KISSING)
        contact = 2.0 * radius * (1.0 + TOUCH_TOLERANCE)
        self._neighbours = fluid_neighbour_list(physics, name, contact, 0.5 * radius)
        self._break = (2.0 + BREAK_GAP) * radius
        self._strength = bond_strength
        self._n = n
        # Bonds in force: index pairs and their constraints; every pair ever bonded (keys
        # i * n + j, sorted), so that a broken bond does not form again.
        self._bi = np.zeros(0, dtype=np.int64)
        self._bj = np.zeros(0, dtype=np.int64)
        self._constraints: list[int] = []
        self._ever = np.zeros(0, dtype=np.int64)
        self.formed = self.broken = 0
        if len(bonds):
            pairs = np.sort(np.asarray(bonds, dtype=np.int64).reshape(-1, 2), axis=1)
            self.set[pairs.ravel()] = True   # only set particles bond
            self._bond(pairs[:, 0], pairs[:, 1], physics.particle_positions(name))
        self._crust(np.flatnonzero(self.set))

    def __call__(self) -> None:
        x = self._physics.particle_state(self.name)[0]
        t = self.temperature
        for source in self._sources:
            touching = ((np.hypot(x[:, 0] - source.centre[0], x[:, 1] - source.centre[1])
                         <= source.radius)
                        & (x[:, 2] - source.top <= self._radius * (1.0 + TOUCH_TOLERANCE))
                        & (x[:, 2] >= source.top - self._radius))
            if touching.any():
                t[touching] += (source.temperature - t[touching]) * self._pan
        i, j, _ = self._neighbours(x)
        if len(i) and self._exchange > 0:
            flow = self._exchange * (t[j] - t[i])
            change = np.bincount(i, flow, self._n) - np.bincount(j, flow, self._n)
            t += change
        if self._air > 0:
            t += (AIR_TEMPERATURE - t) * self._air
        setting = (t >= self._setting) & ~self.set
        if setting.any():
            self.set |= setting
            self._crust(np.flatnonzero(setting))
        if len(self._bi):
            self._break_stretched(x)
        if len(i) and self._strength > 0 and self.set.any():
            both = self.set[i] & self.set[j]
            if both.any():
                i, j = i[both], j[both]
                new = self._never_bonded(i * self._n + j)
                if new.any():
                    self._bond(i[new], j[new], x)

    def thermal_state(self) -> ThermalState:
        """The fluid's temperatures, set flags and bonds in force, now."""
        return ThermalState(self.name, self.temperature.copy(), self.set.copy(),
                            np.stack([self._bi, self._bj], axis=1))

    def _crust(self, particles: np.ndarray) -> None:
        """Make the particles that have just set beads of a crust: no rolling or spinning
        friction (their bonds hold their turning), the crust's friction, and a solid
        sphere's inertia where the raw batter's was raised."""
        change, ids = self._physics.client.changeDynamics, self._ids
        crust = {'rollingFriction': 0.0, 'spinningFriction': 0.0}
        if self._set_friction is not None:
            crust['lateralFriction'] = self._set_friction
        if self._set_inertia is not None:
            crust['localInertiaDiagonal'] = [self._set_inertia] * 3
        for k in particles.tolist():
            change(ids[k], -1, **crust)

    # --- bonds ------------------------------------------------------------------------
    def _bond(self, i: np.ndarray, j: np.ndarray, x: np.ndarray) -> None:
        """Bond the pairs ``(i, j)`` at their midpoints (positions ``x``)."""
        c = self._physics.client
        ids = self._ids
        pose = c.getBasePositionAndOrientation
        constraints = []
        for a, b in zip(i.tolist(), j.tolist()):
            middle = (x[a] + x[b]) / 2.0
            pivots = []
            for body in (ids[a], ids[b]):
                position, orientation = pose(body)
                inverse = c.invertTransform(position, orientation)
                pivots.append(c.multiplyTransforms(*inverse, middle.tolist(),
                                                   (0.0, 0.0, 0.0, 1.0))[0])
            constraint = c.createConstraint(ids[a], -1, ids[b], -1, c.JOINT_POINT2POINT,
                                            (0.0, 0.0, 0.0), pivots[0], pivots[1])
            c.changeConstraint(constraint, maxForce=self._strength)
            constraints.append(constraint)
        self._bi = np.concatenate([self._bi, i])
        self._bj = np.concatenate([self._bj, j])
        self._constraints += constraints
        self._ever = np.union1d(self._ever, i * self._n + j)
        self.formed += len(constraints)

    def _never_bonded(self, key: np.ndarray) -> np.ndarray:
        """Which of the pairs ``key`` (``i * n + j``) never bonded: looked up in the sorted
        keys of those that did."""
        ever = self._ever
        if not len(ever):
            return np.ones(len(key), dtype=bool)
        return ever[np.minimum(np.searchsorted(ever, key), len(ever) - 1)] != key

    def _break_stretched(self, x: np.ndarray) -> None:
        d = x.take(self._bj, axis=0) - x.take(self._bi, axis=0)
        stretched = np.einsum('ij,ij->i', d, d) > self._break * self._break
        if not stretched.any():
            return
        remove = self._physics.client.removeConstraint
        for k in np.flatnonzero(stretched).tolist():
            remove(self._constraints[k])
        keep = ~stretched
        self._bi, self._bj = self._bi[keep], self._bj[keep]
        self._constraints = [c for c, k in zip(self._constraints, keep.tolist()) if k]
        self.broken += int(stretched.sum())
