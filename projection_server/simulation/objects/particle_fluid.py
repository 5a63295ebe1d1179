"""``particle_fluid``: ``particle_count`` spheres, registered as one :class:`Fluid` (contacts
are reported under the fluid's name), their velocities damped by the fluid's ``damping``
(a drag against the world: Bullet decelerates a particle by ``damping * v * (1 + |v|)``),
held together by its ``surface_tension`` and its ``viscosity`` between neighbours
(:mod:`projection_server.simulation.batter.forces`). With a
``container`` (an entity built before it, e.g. the owning cup) they fill its inside from
the bottom in hexagonal layers; given ``positions`` (world [m], e.g. where a projection left
them) they are put there; without either they form a cubic block at the pose.

Heat (:mod:`projection_server.simulation.batter.heat`): each particle starts at the
fluid's ``temperature`` (or its own, ``temperatures``), warms on a heated pancake maker at
``pan_heat_rate`` and exchanges heat with the particles it touches at
``conduction_rate`` (and with the air at ``air_cooling_rate``); from
``setting_temperature`` on it is set (takes ``set_friction``, a cooked crust's, if
given, and has no rolling or spinning friction), and touching set particles bond with
``bond_strength``. ``bonds`` (index pairs) are
bonds made when the world is built."""

from __future__ import annotations

import math
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.batter import BatterForces
from projection_server.simulation.batter.heat import ABSOLUTE_ZERO, BatterHeat, HeatSource
from projection_server.simulation.objects.common import surface
from projection_server.simulation.objects.registry import (ANY, FRACTION, NAME, NONNEGATIVE,
                                                           NUMBERS, ObjectClass, PAIRS, POINTS,
                                                           POSITIVE, Property, register,
                                                           REQUIRED)
from projection_server.simulation.physics import Body, Fluid

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['PARTICLE_FLUID']

PARTICLE_GAP = 1.05      # spacing of spawned particles relative to their diameter


def build(physics: Physics, entity: Entity) -> None:
    c, p = physics.client, entity.properties
    count, radius = int(p['particle_count']), p['particle_radius']
    container = p.get('container')
    if p.get('positions') is not None:
        positions = [list(x) for x in p['positions']]
    elif container is not None:
        if container not in physics.containers:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'{entity.name}: container {container!r} is not built '
                                  'before it or is not a container')
        positions = _container_filling(physics, container, count, radius)
    else:
        positions = _block(entity.pose.xyz, count, radius)
    shape = c.createCollisionShape(c.GEOM_SPHERE, radius=radius)
    dynamics = {'rollingFriction': p['rolling_friction'],
                'spinningFriction': p['spinning_friction'],
                'linearDamping': p['damping'], 'angularDamping': p['damping']}
    if p['rotational_inertia'] != 1.0:
        dynamics['localInertiaDiagonal'] = [_sphere_inertia(p) * p['rotational_inertia']] * 3
    fluid = physics.add_fluid(Fluid(entity.name, radius, []))
    for i, position in enumerate(positions):
        body = c.createMultiBody(p['particle_mass'], shape, -1, position)
        surface(c, body, p)
        c.changeDynamics(body, -1, **dynamics)
        fluid.body_ids.append(body)
        physics.add_body(Body(f'{entity.name}_{i}', entity.cls, body, False, None,
                              group=entity.name))
    if p['surface_tension'] > 0 or p['viscosity'] > 0:
        physics.step_hooks.append(BatterForces(
            physics, entity.name, radius, p['particle_mass'], p['surface_tension'],
            p['viscosity']))
    _heat(physics, entity, radius)


def _heat(physics: Physics, entity: Entity, radius: float) -> None:
    """Attach the fluid's heat (:class:`BatterHeat`) when the scenario has a pancake maker
    (heated or switched off) or the fluid brings a thermal state (temperatures, bonds)."""
    p = entity.properties
    makers = [maker for maker in (physics.scenario.entities if physics.scenario else ())
              if 'heating' in maker.properties and maker.unit.fluid_role is not None]
    sources = [HeatSource(*maker.unit.fluid_role(maker)[1:], maker.properties['temperature'])
               for maker in makers if maker.properties['heating'] > 0]
    if not makers and p.get('temperatures') is None and p.get('bonds') is None:
        return
    count = int(p['particle_count'])
    temperatures = (np.asarray(p['temperatures'], dtype=float) if p.get('temperatures')
                    is not None else np.full(count, p['temperature']))
    physics.step_hooks.append(BatterHeat(
        physics, entity.name, radius, sources, temperatures, p['setting_temperature'],
        p['pan_heat_rate'], p['conduction_rate'], p['air_cooling_rate'],
        p['bond_strength'], p.get('bonds') or (), p.get('set_friction'),
        set_inertia=_sphere_inertia(p) if p['rotational_inertia'] != 1.0 else None))


def _sphere_inertia(p: dict[str, Any]) -> float:
    """A solid sphere's rotational inertia [kg m^2], 2/5 m r^2."""
    return 0.4 * p['particle_mass'] * p['particle_radius'] ** 2


def _check(name: str, p: dict[str, Any]) -> None:
    count = int(p['particle_count'])
    for key in ('temperature', 'setting_temperature'):
        if p[key] < ABSOLUTE_ZERO:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'{name}: {key} = {p[key]} deg C is below absolute zero')
    if p.get('positions') is not None:
        if p.get('container') is not None:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'{name}: positions and container exclude each other')
        if len(p['positions']) != count:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'{name}: {len(p["positions"])} positions for '
                                  f'{count} particles')
    if p.get('temperatures') is not None and (
            len(p['temperatures']) != count or min(p['temperatures']) < ABSOLUTE_ZERO):
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{name}: temperatures must be {count} temperatures '
                              'above absolute zero, one per particle')
    if p.get('bonds') is not None and not all(0 <= i < count and 0 <= j < count and i != j
                                             for i, j in p['bonds']):
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{name}: bonds must pair two particles of the {count}')


def _block(centre: Any, count: int, radius: float) -> list[list[float]]:
    side = math.ceil(count ** (1 / 3))
    spacing = 2 * PARTICLE_GAP * radius
    offset = (side - 1) * spacing / 2
    return [[centre[k] + (n * spacing - offset) for k, n in
             enumerate((i % side, (i // side) % side, i // (side * side)))]
            for i in range(count)]


def _container_filling(physics: Physics, name: str, count: int,
                       radius: float) -> list[list[float]]:
    """World positions of ``count`` particles in hexagonal layers inside a container, from
    its floor up (layers above the rim if they do not fit)."""
    inside = physics.containers[name]
    spacing = 2 * PARTICLE_GAP * radius
    reach = inside.radius - radius * PARTICLE_GAP
    layer = []
    rows = int(reach // (spacing * math.sqrt(3) / 2))
    for j in range(-rows, rows + 1):
        y = j * spacing * math.sqrt(3) / 2
        shift = spacing / 2 if j % 2 else 0.0
        columns = int(reach // spacing) + 1
        for i in range(-columns, columns + 1):
            x = i * spacing + shift
            if x * x + y * y <= reach * reach:
                layer.append((x, y))
    if not layer:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'particles do not fit into {name!r}')
    position, quaternion = physics.pose(name)
    rot = np.asarray(physics.client.getMatrixFromQuaternion(quaternion)).reshape(3, 3)
    out = []
    for k in range(count):
        x, y = layer[k % len(layer)]
        z = inside.bottom + radius * PARTICLE_GAP + (k // len(layer)) * spacing
        out.append(list(np.asarray(position) + rot @ np.array([x, y, z])))
    return out


PARTICLE_FLUID = register(ObjectClass(
    name='particle_fluid',
    properties=(Property('particle_count', REQUIRED, POSITIVE),
                Property('particle_radius', REQUIRED, POSITIVE, 'm'),
                Property('particle_mass', REQUIRED, POSITIVE, 'kg'),
                Property('friction', 0.1, NONNEGATIVE),
                Property('restitution', 0.0, FRACTION),
                Property('rolling_friction', 0.0, NONNEGATIVE, 'm'),
                Property('spinning_friction', 0.0, NONNEGATIVE, 'm'),
                Property('rotational_inertia', 1.0, POSITIVE, '',
                         "a particle's, in solid spheres' (2/5 m r^2); far above 1 it "
                         'slides rather than rolls'),
                Property('damping', 5.0, NONNEGATIVE, '1/s', 'drag against the world'),
                Property('surface_tension', 0.0, NONNEGATIVE, 'N/m',
                         'cohesion between touching particles'),
                Property('viscosity', 0.0, NONNEGATIVE, '1/s',
                         "rate at which neighbours' relative velocity relaxes"),
                Property('container', None, NAME, '', 'the entity it fills'),
                Property('temperature', 20.0, ANY, 'degC', 'initial temperature'),
                Property('setting_temperature', 70.0, ANY, 'degC',
                         'a particle this warm is set (and bonds to set neighbours)'),
                Property('pan_heat_rate', 0.0, NONNEGATIVE, '1/s',
                         "rate towards a heated pan's temperature while touching it"),
                Property('conduction_rate', 0.0, NONNEGATIVE, '1/s',
                         'rate at which touching particles share their temperature'),
                Property('air_cooling_rate', 0.0, NONNEGATIVE, '1/s',
                         'rate towards the air temperature (20 deg C)'),
                Property('bond_strength', 0.0, NONNEGATIVE, 'N',
                         'largest force a bond between set particles holds'),
                Property('set_friction', None, NONNEGATIVE, '',
                         "a set particle's friction (a cooked crust's); absent: friction"),
                Property('positions', None, POINTS, 'm', 'where the particles start'),
                Property('temperatures', None, NUMBERS, 'degC', "each particle's"),
                Property('bonds', None, PAIRS, '', 'particle index pairs bonded at start')),
    fixed={'shape': 'sphere'},
    aliases={'count': ('particle_count', 1.0)},
    build=build,
    check=_check,
    fluid_role=lambda entity: ('fluid', entity.properties['particle_radius']),
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
