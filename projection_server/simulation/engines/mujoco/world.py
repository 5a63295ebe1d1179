"""The one builder from a scenario to a MuJoCo world, and MuJoCo's contact settings.

Each entity is built by its unit's MuJoCo builder (:mod:`.builders`) into one ``MjSpec``
(models are built in code, a URDF robot compiled by MuJoCo's URDF importer and attached);
then the contacts are set up pair by pair, the model compiled once, and each builder's
``after`` step binds what it built (bodies, grippers, object models) to the compiled model.

Contact settings, and why (MuJoCo's documentation: "Computation",
https://mujoco.readthedocs.io/en/latest/computation/index.html, its soft contact model,
friction cones, solver parameters and integrators; "XML Reference",
https://mujoco.readthedocs.io/en/latest/XMLreference.html, ``option/impratio``,
``option/cone``, ``geom/condim``, ``contact/pair``, ``solref``/``solimp``):

* **Elliptic friction cones** (``opt.cone``): the pyramidal default approximates the cone by
  its edges and lets a squeezed object slide earlier; with elliptic cones an egg held 2 cm
  off centre stays held where the pyramidal cone lost it. MuJoCo recommends elliptic cones
  with a large ``impratio`` for grasping: **impratio 10** makes friction stiffer than the
  normal force, so that what is held does not creep ("Contact" / "impratio": "...
  ratio of frictional-to-normal constraint impedance ... typical use is to increase it
  together with elliptic cones, to prevent slip").
* **condim 4**: sliding and torsional friction. A MuJoCo contact is one point; a pad
  pressed on an egg has a patch, whose friction resists the egg's turning about the
  normal (PyBullet's manifold of several points does that). The torsional coefficient is
  the sliding one times :data:`TORSION_ARM`: (2/3) r of a patch of radius r = 4.5 mm, the
  torque of a uniform pressure's friction over the pad's contact patch. No rolling
  friction (condim 6 costs more and the scenarios' rolling resistances are small).
* **Friction of a pair = the product of the two bodies' coefficients**, as in Bullet
  (``btManifoldResult::calculateCombinedFriction``), so that the scenarios' coefficients
  mean the same on both engines; MuJoCo's own rule would take the larger. Hence every
  contact is an explicit ``<pair>`` (geoms' ``contype``/``conaffinity`` 0), between
  bodies of different entities, not both static.
* **solref (0.01, 1)**: a critically damped contact of 10 ms time constant (the default
  0.02 sinks an egg on its table further; with it an egg let go 1 or 1.5 cm above the
  table was not seen to drop);
  **solimp** MuJoCo's default (0.9, 0.95, 0.001). The time constant is a time, not a
  fraction of a step: a finer step keeps the contacts as stiff. MuJoCo keeps it at least
  twice the step ("refsafe"): 16.7 ms at its default 120 Hz (``engines.mujoco`` of
  config/physics.yaml), 10 ms from 240 Hz on.
* **ccd_tolerance 1e-9** (MuJoCo's default 1e-6): an ellipsoid on a box (the egg on the
  table) collides through MuJoCo's general convex collision, whose contact point lies up
  to 6 um off the point under the centre at the default tolerance; with no rolling
  friction that offset's torque rolls an egg at rest about its long axis, 1 mm in its
  first second. At 1e-9 the offset is below 0.1 um.
* **Newton solver**, ``solver_iterations`` of the settings, the semi-implicit **Euler**
  integrator: there are no stiff servos to integrate implicitly (a gripper's joints are
  set their speeds, :class:`~.physics.MujocoGripper`), and MuJoCo solves the constraints
  with the plain inertia, which an implicit servo's would contradict ("Numerical
  integration").

Restitution is not modelled (MuJoCo's contacts are damped springs; a critically damped
one does not bounce).
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable, TYPE_CHECKING

import mujoco

from projection_server import assets
from projection_server.simulation.engines.mujoco.physics import MujocoPhysics
from projection_server.simulation.scenario import model_files

if TYPE_CHECKING:
    from projection_server.settings import Settings
    from projection_server.simulation.scenario import Entity, Scenario

__all__ = ['CCD_TOLERANCE', 'CONE', 'CONDIM', 'IMPRATIO', 'SOLREF', 'SOLIMP', 'TORSION_ARM',
           'TUNED', 'WorldSpec', 'build_world']

CONE = mujoco.mjtCone.mjCONE_ELLIPTIC
IMPRATIO = 10.0
CONDIM = 4
TORSION_ARM = 0.003       # m: (2/3) x 4.5 mm, a pad's contact patch
SOLREF = (0.01, 1.0)      # s, damping ratio
SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
CCD_TOLERANCE = 1e-9      # m: of the general convex collision's contact (module doc)
SPAWN_CLEARANCE = 1e-4    # m left between a spawned body and what it would penetrate


@dataclass
class _Geom:
    name: str
    entity: str
    kind: str          # 'static', 'dynamic' or 'robot'
    friction: float
    tuned: bool = False   # the friction is the entity's ``friction`` property


@dataclass
class WorldSpec:
    """A world under construction: the spec, and what the builders registered."""

    spec: Any
    settings: Settings
    scenario: Scenario
    tool_control: bool
    geoms: list[_Geom] = field(default_factory=list)
    after: list[Callable[[MujocoPhysics], None]] = field(default_factory=list)
    # Set a compiled model's numbers from a scenario of the same shape (TUNED); True if
    # they changed a body's mass (the model's mass-dependent constants are then set anew).
    tuners: list[Callable[[Any, Scenario], bool]] = field(default_factory=list)
    pairs: list[tuple[int, int]] = field(default_factory=list)   # geoms of each pair
    gravity: float | None = None

    def geom(self, body: Any, entity: str, kind: str, friction: float, tuned: bool = False,
             **attributes: Any) -> Any:
        """A geom of ``entity`` on ``body``, colliding through the pairs of the world;
        ``tuned``: its friction is the entity's ``friction`` property (one of
        :data:`TUNED`), which a model compiled for another value is given."""
        name = f'{entity}#{len(self.geoms)}'
        geom = body.add_geom(name=name, contype=0, conaffinity=0, **attributes)
        self.geoms.append(_Geom(name, entity, kind, float(friction), tuned))
        return geom

    def adopt(self, geom: Any, entity: str, kind: str, friction: float) -> None:
        """Register a geom a builder got from elsewhere (an attached URDF)."""
        geom.name = f'{entity}#{len(self.geoms)}'
        geom.contype, geom.conaffinity = 0, 0
        self.geoms.append(_Geom(geom.name, entity, kind, float(friction)))


def build_world(scenario: Scenario, settings: Settings, tool_control: bool = False
                ) -> MujocoPhysics:
    """A fresh world of ``scenario``: a copy of its compiled model, its own data, and what
    the builders bind to them.

    A model is compiled once per scenario *shape*, settings and content of its model files
    in a process (an edited mesh is compiled anew): scenarios that differ only in
    properties of :data:`TUNED` (a query's parametrizations, a belief's worlds) share it,
    each copy given its own scenario's numbers: the pairs' frictions, a
    body's mass and inertia and the constants MuJoCo's compiler derives from the masses
    (``mj_setConst``'s, and the mean mass and inertia that scale the solver's tolerance).
    The copy is the model that compiling the scenario gives, bit for bit
    (test/simulation/test_mujoco_models.py compares every field)."""
    files = tuple((path, assets.digest(path)) for path in model_files(scenario))
    key = (repr(_shape(scenario)), repr(settings.physics), tool_control, files)
    compiled = _COMPILED.get(key)
    if compiled is None:
        compiled = _compile(scenario, settings, tool_control)
        if len(_COMPILED) >= 16:
            del _COMPILED[next(iter(_COMPILED))]
        _COMPILED[key] = compiled
    else:
        _COMPILED[key] = _COMPILED.pop(key)   # the most recently used is kept longest
    template, after, world = compiled
    model = copy.copy(template)   # a projection changes its model (motors, a broken egg)
    data = mujoco.MjData(model)
    _tune(model, data, world, scenario)
    physics = MujocoPhysics(model, data, settings, scenario, tool_control)
    for bind in after:
        bind(physics)
    physics.bind()
    mujoco.mj_forward(model, data)
    _lift_clear(physics)
    return physics


# Per object class, the properties that a compiled model holds only as numbers that
# :func:`_tune` sets (or that MuJoCo's builders do not read): a scenario's shape is the
# scenario without them. A builder of such a class reads them from the scenario the world
# is built for (``physics.scenario``), never from the one its model was compiled from.
TUNED: dict[str, frozenset[str]] = {
    'egg': frozenset({'friction', 'mass', 'breaking_force', 'restitution',
                      'rolling_friction', 'spinning_friction'}),
    'table': frozenset({'friction', 'restitution'}),
    'floor': frozenset({'friction', 'restitution'}),
}


def _shape(scenario: Scenario) -> Scenario:
    """``scenario`` without the properties of :data:`TUNED`."""
    entities = []
    for entity in scenario.entities:
        tuned = TUNED.get(entity.cls)
        if tuned:
            entity = dataclasses.replace(entity, properties={
                k: v for k, v in entity.properties.items() if k not in tuned})
        entities.append(entity)
    return dataclasses.replace(scenario, entities=tuple(entities))


def _tune(model: Any, data: Any, world: WorldSpec, scenario: Scenario) -> None:
    """Give ``model`` (compiled from ``world``) the numbers of ``scenario`` (of the same
    shape): set as the compiler sets them, in the same order of operations."""
    entities = {entity.name: entity for entity in scenario.entities}
    friction = [entities[g.entity].properties['friction'] if g.tuned else g.friction
                for g in world.geoms]
    pair_friction = model.pair_friction
    for pair, (a, b) in enumerate(world.pairs):
        mu = friction[a] * friction[b]
        pair_friction[pair] = (mu, mu, mu * TORSION_ARM, 0.0, 0.0)
    changed = False
    for tune in world.tuners:
        changed = tune(model, scenario) or changed
    if not changed:
        return
    # What MuJoCo's compiler derives from the masses: mj_setConst's constants at qpos0,
    # then (as its set0 does) the mean body mass and the mean of the mass matrix's diagonal.
    mujoco.mj_setConst(model, data)
    mean = 0.0
    for body in range(1, model.nbody):
        mean += float(model.body_mass[body])
    model.stat.meanmass = mean / (model.nbody - 1)
    data.qpos[:] = model.qpos0
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_crb(model, data)
    inertia, rows, counts = data.M, model.M_rowadr, model.M_rownnz
    mean = 0.0
    for dof in range(model.nv):
        mean += float(inertia[rows[dof] + counts[dof] - 1])
    model.stat.meaninertia = mean / model.nv
    mujoco.mj_resetData(model, data)


# (scenario shape, physics settings, tool control, model files' digests) -> (compiled
# model, the builders' binders, the world it was compiled from)
_COMPILED: dict[tuple[str, str, bool, tuple[tuple[str, str], ...]],
                tuple[Any, list[Callable[[MujocoPhysics], None]], WorldSpec]] = {}


def _compile(scenario: Scenario, settings: Settings, tool_control: bool
             ) -> tuple[Any, list[Callable[[MujocoPhysics], None]], WorldSpec]:
    from projection_server.simulation.engines.mujoco.builders import object_builder

    s = settings.physics
    spec = mujoco.MjSpec()
    spec.modelname = scenario.name or 'world'
    option = spec.option
    option.timestep = s.time_step
    option.gravity = list(s.gravity)
    option.iterations = s.solver_iterations
    option.ls_iterations = max(10, s.solver_iterations // 2)
    option.cone = CONE
    option.impratio = IMPRATIO
    option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    option.solver = mujoco.mjtSolver.mjSOL_NEWTON
    option.ccd_tolerance = CCD_TOLERANCE
    world = WorldSpec(spec, settings, scenario, tool_control)
    for entity in scenario.entities:
        build = object_builder(entity.cls)
        if build is not None:
            build(world, entity)
    if world.gravity is not None:
        option.gravity = [0.0, 0.0, -world.gravity]
    _pairs(world)
    model = spec.compile()
    return model, world.after, world


def _pairs(world: WorldSpec) -> None:
    """An explicit contact pair for every two geoms of different entities that may touch
    (not both static, not both robots'), of the product of their frictions."""
    geoms = world.geoms
    for i, a in enumerate(geoms):
        for j, b in enumerate(geoms[i + 1:], i + 1):
            if a.entity == b.entity or (a.kind == b.kind and a.kind != 'dynamic'):
                continue
            world.pairs.append((i, j))
            mu = a.friction * b.friction
            world.spec.add_pair(name=f'{a.name}|{b.name}', geomname1=a.name,
                                geomname2=b.name, condim=CONDIM,
                                friction=[mu, mu, mu * TORSION_ARM, 0.0, 0.0],
                                solref=list(SOLREF), solimp=list(SOLIMP))


def _lift_clear(physics: MujocoPhysics) -> None:
    """Raise each free body out of what it penetrates at its spawn pose (a pose given as the
    nominal contact touches within the engine's tolerance), in the scenario's order."""
    model, data = physics.model, physics.data
    for body in physics.bodies.values():
        dof = physics._free.get(body.body_id)
        if dof is None:
            continue
        joint = int(model.body_jntadr[body.body_id])
        address = int(model.jnt_qposadr[joint])
        for _ in range(4):
            depth = 0.0
            for i in range(data.ncon):
                owners = physics._owner[data.contact.geom[i]]
                if body.body_id in (owners[0][0], owners[1][0]):
                    depth = max(depth, -float(data.contact.dist[i]))
            if depth <= 0.0:
                break
            data.qpos[address + 2] += depth + SPAWN_CLEARANCE
            mujoco.mj_forward(model, data)
