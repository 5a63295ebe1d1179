"""MuJoCo: the second engine, with a contact model unlike Bullet's (soft, convex, elliptic
friction cones). An ``MjModel`` is compiled from an ``MjSpec`` built in code (:mod:`.world`,
contact settings and their sources there) once per scenario shape in a process, and each
projection gets a copy of it with its own scenario's numbers (frictions, masses) and its
own ``MjData``: what one world does never reaches another. The builders of the units it
can build are in :mod:`.builders`.

Past this machine, MuJoCo Warp steps the same ``MjModel`` batched on a GPU: a batch of
worlds of one scenario differs only in its ``MjData``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from projection_server.simulation.engines import Engine

if TYPE_CHECKING:
    from projection_server.settings import Settings
    from projection_server.simulation.engines.mujoco.physics import MujocoPhysics
    from projection_server.simulation.scenario import Scenario

__all__ = ['ENGINE', 'MujocoSession']


class MujocoSession:
    """Builds MuJoCo worlds (one model and data each)."""

    def __init__(self) -> None:
        import mujoco  # noqa: F401 (imported once per process, before the first world)

    def build_world(self, scenario: Scenario, settings: Settings,
                    tool_control: bool = False) -> MujocoPhysics:
        from projection_server.simulation.engines.mujoco.world import build_world

        return build_world(scenario, settings, tool_control)

    def close(self) -> None:
        pass


def _object_builder(name: str):
    from projection_server.simulation.engines.mujoco.builders import object_builder

    return object_builder(name)


def _robot_builder(name: str):
    from projection_server.simulation.engines.mujoco.builders import robot_builder

    return robot_builder(name)


# MjModel and MjData copy deeply: a copy of a projection steps on exactly.
ENGINE = Engine('mujoco', MujocoSession, _object_builder, _robot_builder, copyable=True)
