"""The one builder from a scenario description to a PyBullet world.

Every physical property comes from the scenario or from an asset file; the engine's own
settings come from ``config/physics.yaml``. Each entity is built by its class's unit in the
object class registry (:mod:`projection_server.simulation.objects`: each module's doc says
how its class becomes bodies), in the scenario's order; a class without a builder (a
robot's gripper) is built by the entity that owns it.
"""

from __future__ import annotations

import math
from typing import Any, TYPE_CHECKING

from projection_server.simulation.objects import get as object_class
from projection_server.simulation.physics import Physics

if TYPE_CHECKING:
    from projection_server.settings import PhysicsSettings, Settings
    from projection_server.simulation.scenario import Scenario

__all__ = ['build_world', 'settle']

SETTLE_CHECK = 0.01      # s of settling between checks whether the world is at rest
SETTLE_MIN, SETTLE_MAX = 0.1, 1.0   # s of settling at least and at most
REST_SPEED = 1e-3        # m/s (and rad/s per 0.1 m) below which a body is at rest


def build_world(client: Any, scenario: Scenario, settings: Settings,
                tool_control: bool = False) -> Physics:
    """Configure ``client`` from ``settings`` and build every entity of ``scenario`` in it;
    with ``tool_control``, robots as manipulators whose tool a plan moves."""
    _configure(client, settings.physics)
    physics = Physics(client, settings, scenario, tool_control)
    for entity in scenario.entities:
        build = object_class(entity.cls).build
        if build is not None:
            build(physics, entity)
    return physics


def settle(physics: Physics) -> float:
    """Let the world come to rest before a program starts; returns the seconds it took.

    The engine is stepped without object models and without advancing the projection's
    clock, for at least :data:`SETTLE_MIN` and until every moving body is slower than
    :data:`REST_SPEED` (at most :data:`SETTLE_MAX`), so that every projection starts from
    a world at rest whatever its time step: contacts of bodies spawned onto each other
    carry their weights, not a recovery from a spawn.
    """
    rate = physics.settings.physics.rate_hz
    chunk = max(1, round(SETTLE_CHECK * rate))
    moving = [b.body_id for b in physics.bodies.values()
              if not b.static and not b.driven]
    steps = 0
    while steps < SETTLE_MAX * rate:
        physics.step_unmonitored(chunk)
        steps += chunk
        if steps >= SETTLE_MIN * rate and all(_at_rest(physics, body) for body in moving):
            break
    return steps / rate


def _at_rest(physics: Physics, body_id: int) -> bool:
    linear, angular = physics.base_velocity(body_id)
    return (math.hypot(*linear) < REST_SPEED
            and 0.1 * math.hypot(*angular) < REST_SPEED)


def _configure(client: Any, s: PhysicsSettings) -> None:
    client.resetSimulation()
    client.setPhysicsEngineParameter(
        fixedTimeStep=s.time_step, numSubSteps=0, numSolverIterations=s.solver_iterations,
        erp=s.erp, contactERP=s.contact_erp, frictionERP=s.friction_erp,
        contactBreakingThreshold=s.contact_breaking_threshold,
        solverResidualThreshold=s.solver_residual_threshold,
        deterministicOverlappingPairs=s.deterministic_overlapping_pairs)
    client.setGravity(*s.gravity)
