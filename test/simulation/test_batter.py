"""The batter's forces between particles: neighbour pairs are exact, a liquid bridge pulls
touching particles together and lets go past its rupture gap, viscosity conserves momentum and
relaxes relative velocity at its rate whatever the time step."""

from __future__ import annotations

import gc
import math
import weakref

import numpy as np
import pybullet
import pytest

from projection_server.settings import load_settings
from projection_server.simulation.batter import (BatterForces, fluid_neighbour_list,
                                                 NeighbourList, NeighbourLists, pairs)
from projection_server.simulation.batter.forces import RUPTURE_GAP
from projection_server.simulation.physics import Body, Fluid, Physics, bound_client

R, MASS = 0.0048, 0.0005


def brute_force(x, cutoff):
    d = np.linalg.norm(x[:, None] - x[None], axis=2)
    return set(zip(*map(list, np.nonzero(np.triu(d < cutoff, 1)))))


@pytest.mark.parametrize('n, scale', [(2, 0.01), (50, 0.05), (300, 0.1), (300, 0.03)])
def test_pairs_are_every_pair_closer_than_the_cutoff(n, scale):
    x = np.random.default_rng(n).random((n, 3)) * scale - scale / 2
    i, j, d = pairs(x, 0.012)
    assert set(zip(i.tolist(), j.tolist())) == brute_force(x, 0.012)
    assert len(i) == len(set(zip(i.tolist(), j.tolist())))
    assert (i < j).all() and np.allclose(d, x[j] - x[i])


def test_the_verlet_list_misses_no_pair_as_points_move():
    rng = np.random.default_rng(3)
    x = rng.random((200, 3)) * 0.06
    neighbours = NeighbourList(0.012, 0.0024)
    for _ in range(60):
        x = x + rng.normal(0, 0.0001, x.shape)
        i, j, _ = neighbours(x)
        assert set(zip(i.tolist(), j.tolist())) == brute_force(x, 0.012)
    assert 1 < neighbours.rebuilds < 60   # rebuilt only when something moved far enough


def test_lists_sharing_their_verlet_lists_give_what_lists_of_their_own_do_to_the_bit():
    rng = np.random.default_rng(5)
    x = rng.random((300, 3)) * 0.05
    shared = NeighbourLists(0.0024)
    lists = [(NeighbourList(cutoff, 0.0024, shared), NeighbourList(cutoff, 0.0024))
             for cutoff in (0.012, 0.0101, 0.006)]
    for _ in range(40):
        x = x + rng.normal(0, 0.0003, x.shape)
        for drawn, own in lists:
            for a, b in zip(drawn(x), own(x)):
                assert a.dtype == b.dtype and np.array_equal(a, b)   # the same order too
    assert shared.rebuilds == lists[0][1].rebuilds > 1


def test_the_lists_of_a_worlds_fluid_and_skin_share_their_rebuilds_and_go_with_the_world():
    physics, other = world(), world()
    forces = fluid_neighbour_list(physics, 'mix', 0.012, 0.0024)
    heat = fluid_neighbour_list(physics, 'mix', 0.0101, 0.0024)
    apart = [fluid_neighbour_list(physics, 'mix', 0.012, 0.003),
             fluid_neighbour_list(physics, 'dough', 0.012, 0.0024),
             fluid_neighbour_list(other, 'mix', 0.012, 0.0024)]
    x = np.random.default_rng(7).random((100, 3)) * 0.05
    for neighbours in [forces, heat, *apart]:
        neighbours(x)
    forces(x + 0.01)   # moved past half the skin: rebuilt, for the heat's list too
    assert forces.rebuilds == heat.rebuilds == 2
    assert [neighbours.rebuilds for neighbours in apart] == [1, 1, 1]
    for p in (physics, other):
        p.client.disconnect()
    gone = weakref.ref(physics)
    del physics
    gc.collect()
    assert gone() is None   # its lists do not keep a world alive


def world(rate_hz=240, gravity=0.0):
    """A Physics of free particles (no gravity unless asked for), at ``rate_hz``."""
    settings = load_settings().for_projection('pour', {'rate_hz': rate_hz})
    client = bound_client(pybullet.DIRECT)
    client.setTimeStep(1 / rate_hz)
    client.setGravity(0, 0, -gravity)
    return Physics(client, settings)


def particles(physics, positions, velocities=None, surface_tension=0.0, viscosity=0.0):
    c = physics.client
    fluid = physics.add_fluid(Fluid('mix', R, []))
    shape = c.createCollisionShape(c.GEOM_SPHERE, radius=R)
    for k, position in enumerate(positions):
        body = c.createMultiBody(MASS, shape, -1, position)
        c.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0)
        if velocities is not None:
            c.resetBaseVelocity(body, velocities[k])
        fluid.body_ids.append(body)
        physics.add_body(Body(f'mix_{k}', 'particle_fluid', body, False, None, group='mix'))
    forces = BatterForces(physics, 'mix', R, MASS, surface_tension, viscosity)
    physics.step_hooks.append(forces)
    return fluid


def gap_after(physics, fluid, seconds):
    for _ in range(round(seconds * physics.settings.physics.rate_hz)):
        physics.step()
    x = physics.particle_positions('mix')
    return float(np.linalg.norm(x[1] - x[0]) - 2 * R)


@pytest.mark.parametrize('gap, closes', [(0.3 * R, True), (1.2 * RUPTURE_GAP * R, False)])
def test_a_bridge_pulls_particles_together_only_within_its_rupture_gap(gap, closes):
    physics = world()
    fluid = particles(physics, [[0, 0, 1], [2 * R + gap, 0, 1]], surface_tension=1.0)
    after = gap_after(physics, fluid, 0.2)
    physics.client.disconnect()
    assert (after < 0.05 * R) if closes else after == pytest.approx(gap, abs=1e-9)


def test_without_surface_tension_nothing_pulls():
    physics = world()
    fluid = particles(physics, [[0, 0, 1], [2.3 * R, 0, 1]], viscosity=0.0,
                      surface_tension=0.0)
    assert gap_after(physics, fluid, 0.2) == pytest.approx(0.3 * R, abs=1e-9)
    physics.client.disconnect()


def relative_speed(rate_hz, viscosity, seconds=0.05):
    """Two touching particles sliding past each other at 1 cm/s, without friction: their
    relative speed after ``seconds``, and their total momentum before and after."""
    physics = world(rate_hz)
    fluid = particles(physics, [[0, 0, 1], [2 * R, 0, 1]],
                      velocities=[[0, 0.005, 0], [0, -0.005, 0]], viscosity=viscosity)
    for body in fluid.body_ids:
        physics.client.changeDynamics(body, -1, lateralFriction=0.0)
    physics.step_hooks[-1]()   # the forces of the state at 0 s act in the first step
    for _ in range(round(seconds * rate_hz)):
        physics.step()
    _, v = physics.particle_state('mix', velocities=True)
    physics.client.disconnect()
    return float(v[0, 1] - v[1, 1]), v.sum(axis=0)


def test_viscosity_relaxes_relative_velocity_at_its_rate_whatever_the_step():
    coarse, momentum = relative_speed(240, 200.0)
    fine, _ = relative_speed(960, 200.0)
    free, _ = relative_speed(240, 0.0)
    assert free == pytest.approx(0.01, rel=1e-6)
    # One neighbour of KISSING: the pair's relative velocity decays at 2 * 200 / 12 per s.
    expected = 0.01 * math.exp(-2 * 200.0 / 12 * 0.05)
    assert coarse == pytest.approx(expected, rel=0.05)
    assert fine == pytest.approx(coarse, rel=0.03)
    assert np.abs(momentum).max() < 1e-9   # the pair's momentum stays zero
