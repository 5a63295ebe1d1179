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
* **solref (0.01, 1)**: a critically damped contact of 10 ms time constant, twice 1/240 s
  at least, as MuJoCo requires of a time constant (the default 0.02 sinks an egg on its
  table further); **solimp** MuJoCo's default (0.9, 0.95, 0.001). The time constant is a
  time, not a fraction of a step: a finer step keeps the contacts as stiff.
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
           'WorldSpec', 'build_world']

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


@dataclass
class WorldSpec:
    """A world under construction: the spec, and what the builders registered."""

    spec: Any
    settings: Settings
    scenario: Scenario
    tool_control: bool
    geoms: list[_Geom] = field(default_factory=list)
    after: list[Callable[[MujocoPhysics], None]] = field(default_factory=list)
    gravity: float | None = None

    def geom(self, body: Any, entity: str, kind: str, friction: float, **attributes: Any
             ) -> Any:
        """A geom of ``entity`` on ``body``, colliding through the pairs of the world."""
        name = f'{entity}#{len(self.geoms)}'
        geom = body.add_geom(name=name, contype=0, conaffinity=0, **attributes)
        self.geoms.append(_Geom(name, entity, kind, float(friction)))
        return geom

    def adopt(self, geom: Any, entity: str, kind: str, friction: float) -> None:
        """Register a geom a builder got from elsewhere (an attached URDF)."""
        geom.name = f'{entity}#{len(self.geoms)}'
        geom.contype, geom.conaffinity = 0, 0
        self.geoms.append(_Geom(geom.name, entity, kind, float(friction)))


def build_world(scenario: Scenario, settings: Settings, tool_control: bool = False
                ) -> MujocoPhysics:
    """A fresh world of ``scenario``: a copy of its compiled model (compiled once per
    scenario, settings and content of its model files in a process: a query's
    parametrizations share it), its own data, and what the builders bind to them."""
    # frozen dataclasses; and the model files' contents: an edited mesh is compiled anew
    files = tuple((path, assets.digest(path)) for path in model_files(scenario))
    key = (repr(scenario), repr(settings.physics), tool_control, files)
    compiled = _COMPILED.get(key)
    if compiled is None:
        compiled = _compile(scenario, settings, tool_control)
        if len(_COMPILED) >= 16:
            del _COMPILED[next(iter(_COMPILED))]
        _COMPILED[key] = compiled
    else:
        _COMPILED[key] = _COMPILED.pop(key)   # the most recently used is kept longest
    template, after = compiled
    model = copy.copy(template)   # a projection changes its model (motors, a broken egg)
    data = mujoco.MjData(model)
    physics = MujocoPhysics(model, data, settings, scenario, tool_control)
    for bind in after:
        bind(physics)
    physics.bind()
    mujoco.mj_forward(model, data)
    _lift_clear(physics)
    return physics


# (scenario, physics settings, tool control, model files' digests) -> (compiled model, the
# builders' binders)
_COMPILED: dict[tuple[str, str, bool, tuple[tuple[str, str], ...]],
                tuple[Any, list[Callable[[MujocoPhysics], None]]]] = {}


def _compile(scenario: Scenario, settings: Settings, tool_control: bool
             ) -> tuple[Any, list[Callable[[MujocoPhysics], None]]]:
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
    return spec.compile(), world.after


def _pairs(world: WorldSpec) -> None:
    """An explicit contact pair for every two geoms of different entities that may touch
    (not both static, not both robots'), of the product of their frictions."""
    geoms = world.geoms
    for i, a in enumerate(geoms):
        for b in geoms[i + 1:]:
            if a.entity == b.entity or (a.kind == b.kind and a.kind != 'dynamic'):
                continue
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
