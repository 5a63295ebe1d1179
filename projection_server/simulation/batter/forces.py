"""Cohesion and viscosity between the particles of a batter: a step hook per fluid.

A particle stands for a blob of batter, and two blobs that touch share a liquid bridge.

* **Cohesion** (surface tension ``gamma`` [N/m]): the capillary force of a bridge between two
  equal spheres of radius ``R`` that the liquid wets, ``F0 = 2 pi R* gamma`` with the
  Derjaguin radius ``R* = R / 2``, i.e. ``F0 = pi R gamma`` (Israelachvili, *Intermolecular
  and Surface Forces*, ch. 17). It is greatest at contact and falls linearly to zero at the
  bridge's rupture gap :data:`RUPTURE_GAP` x ``R`` (Lian, Thornton and Adams 1993: rupture
  at a gap of the order of the bridge volume's cube root). Only this attractive branch is
  modelled; Bullet's contacts are the repulsion (as in the attractive lobe of Akinci et al.
  2013's cohesion kernel).
* **Viscosity** (``viscosity`` [1/s]): neighbours' relative velocity relaxes at that rate,
  as in XSPH velocity smoothing. Each step a pair exchanges the momentum that decays its
  relative velocity by ``exp(-2 viscosity w dt / KISSING)``, with ``w`` the bridge's weight
  (1 at contact, 0 at rupture): a particle surrounded by :data:`KISSING` touching
  neighbours relaxes towards their mean velocity at about ``viscosity``. Pairwise and
  antisymmetric, so it conserves momentum; exponential in ``dt``, so it converges in the
  time step (and stays stable while ``viscosity dt`` is below about 1).

Per step: one batched read of the particles' positions (and velocities, for viscosity;
:meth:`Physics.particle_state`), numpy over the pairs within the rupture distance
(a Verlet list, :class:`~.neighbours.NeighbourList`, shared with the batter's heat:
:func:`~.neighbours.fluid_neighbour_list`), one ``bincount`` of the pairs' forces and one
``applyExternalForce`` per particle that has a neighbour.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from projection_server.simulation.batter.neighbours import fluid_neighbour_list

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics

__all__ = ['BatterForces', 'KISSING', 'RUPTURE_GAP']

RUPTURE_GAP = 0.5   # a bridge breaks at a gap of this many particle radii
KISSING = 12        # touching neighbours of a particle in a dense packing
_AXES = np.arange(3)


class BatterForces:
    """Cohesion and viscosity among the particles of fluid ``name`` of ``physics``
    (``radius`` [m], ``mass`` [kg] each); call it after every physics step."""

    def __init__(self, physics: Physics, name: str, radius: float, mass: float,
                 surface_tension: float, viscosity: float):
        self._physics = physics
        self._name = name
        self._ids = physics.fluids[name].body_ids
        self._contact = 2 * radius
        self._cutoff = (2 + RUPTURE_GAP) * radius
        self._neighbours = fluid_neighbour_list(physics, name, self._cutoff,
                                               RUPTURE_GAP * radius)
        self._bridge = math.pi * radius * surface_tension          # N at contact
        self._dt = dt = 1.0 / physics.settings.physics.rate_hz
        self._rate = 2 * viscosity * dt / KISSING   # a touching pair's decay exponent a step
        self._momentum = mass / 2 / dt              # as a force: half the relative velocity
        self._apply = physics.client.applyExternalForce
        self._frame = physics.client.WORLD_FRAME
        self.pairs = 0   # pairs within the rupture distance at the last step

    def __call__(self) -> None:
        viscous = self._rate > 0
        x, v = self._physics.particle_state(self._name, velocities=viscous)
        i, j, d = self._neighbours(x)
        self.pairs = len(i)
        if not len(i):
            return
        distance = np.sqrt(np.einsum('ij,ij->i', d, d))
        weight = np.clip((self._cutoff - distance) / (self._cutoff - self._contact), 0.0, 1.0)
        ends, parts = [], []
        if self._bridge > 0:
            pull = (self._bridge * weight / np.maximum(distance, 1e-9))[:, None] * d
            ends += (i, j)
            parts += (pull, -pull)
        if viscous:
            relative = v.take(j, axis=0) - v.take(i, axis=0)
            drag = (self._momentum * -np.expm1(-self._rate * weight))[:, None] * relative
            ends += (i, j)
            parts += (drag, -drag)
        force = _sums(ends, parts, len(x))
        touched = np.zeros(len(x), dtype=bool)
        touched[i] = True
        touched[j] = True
        apply, frame, ids = self._apply, self._frame, self._ids
        force, at = force.tolist(), x.tolist()
        for k in np.flatnonzero(touched).tolist():
            apply(ids[k], -1, force[k], at[k], frame)


def _sums(ends: list[np.ndarray], parts: list[np.ndarray], n: int) -> np.ndarray:
    """The (n, 3) sums of the rows of ``parts`` over the particles ``ends`` name, each sum
    taken in the order the rows come (one ``bincount`` over all three axes)."""
    if not ends:
        return np.zeros((n, 3))
    end = np.concatenate(ends)
    slot = (3 * end)[:, None] + _AXES
    return np.bincount(slot.ravel(), np.concatenate(parts).ravel(), 3 * n).reshape(n, 3)
