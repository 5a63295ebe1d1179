"""``wait(duration)``: no robot acts; the world runs for ``duration`` seconds as the scenario
sets it up. For questions about the world alone: will this stack stand, does a glass
that falls from here break, where does a ball roll to."""

from __future__ import annotations

from typing import TYPE_CHECKING

from projection_server.simulation.programs.registry import Parameter, Program, register

if TYPE_CHECKING:
    import numpy as np

    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Scenario

__all__ = ['PROGRAM', 'Wait']


class Wait:
    """The task: nothing to command, for ``duration`` seconds."""

    def __init__(self, physics: Physics, scenario: Scenario, params: dict[str, float],
                 rng: np.random.Generator):
        self.duration = params['duration']

    def control(self, physics: Physics) -> None:
        pass


PROGRAM = register(Program(
    name='wait',
    params=(Parameter('duration', 's', 0.1, 60.0, 2.0, 'how long the world runs'),),
    create=Wait,
    doc=__doc__.splitlines()[0],
    engines=('pybullet', 'mujoco'),
))
