"""What a batter does beyond rigid spheres: the physics between its particles.

* :mod:`.neighbours`: the pairs of particles within a range, from one batched read of their
  positions (a cell grid in numpy); the lists of one fluid share one Verlet list
  (:func:`.neighbours.fluid_neighbour_list`).
* :mod:`.forces`: cohesion (a liquid bridge between neighbours: surface tension) and
  viscosity (neighbours' relative velocity damped), one batched write of forces per step.

A particle fluid's builder attaches them as step hooks when its properties ask for them.
"""

from projection_server.simulation.batter.forces import BatterForces
from projection_server.simulation.batter.neighbours import (fluid_neighbour_list, NeighbourList,
                                                             NeighbourLists, pairs)

__all__ = ['BatterForces', 'NeighbourList', 'NeighbourLists', 'fluid_neighbour_list', 'pairs']
