"""PyBullet: the default engine. Its builders are the units' own (``ObjectClass.build``,
``RobotModel.build``); a session keeps one DIRECT-mode client for many worlds."""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from projection_server.simulation.engines import Engine

if TYPE_CHECKING:
    from projection_server.settings import Settings
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Scenario

__all__ = ['ENGINE', 'BulletSession']


class BulletSession:
    """A warm DIRECT-mode PyBullet client; each world is built afresh in it."""

    engine = 'pybullet'

    def __init__(self, client: Any = None) -> None:
        """A new client, or the session of ``client`` (one a caller holds)."""
        if client is None:
            import pybullet

            from projection_server.simulation.physics import bound_client

            client = bound_client(pybullet.DIRECT)
        self.client = client

    def build_world(self, scenario: Scenario, settings: Settings,
                    tool_control: bool = False) -> Physics:
        from projection_server.simulation.world import build_world

        return build_world(self.client, scenario, settings, tool_control)

    def close(self) -> None:
        self.client.disconnect()


def _object_builder(name: str) -> Any:
    from projection_server.simulation.objects import get

    return get(name).build


def _robot_builder(name: str) -> Any:
    from projection_server.simulation import robots

    return robots.get(name).build


ENGINE = Engine('pybullet', BulletSession, _object_builder, _robot_builder)
