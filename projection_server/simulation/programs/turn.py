"""``turn_pancake(angle)``: turn the pancake on the pancake maker over with the spatula.

The pancake is the scenario's first ``pancake``, or, without one, its first particle fluid
placed by ``positions`` (batter that a projection left on the pan, set or raw; its centre
is the particles' centroid, its radius their largest horizontal distance from it plus a
particle radius).

The spatula's blade, tilted ``angle`` radians to the horizontal (front edge down), starts
with its front edge just outside the pancake's rim on the side of the spatula's scenario
pose (-x of the pancake, the blade pointing +x) and :data:`CLEARANCE` above the maker. It is
pushed along +x at :data:`PUSH_SPEED` on average (smooth start and stop) until its
front edge is :data:`REACH` of the pancake's radius past the pancake's centre, then turned
quickly (:data:`LEVEL_TIME`) about its front edge to :data:`CARRY_PITCH` (front edge up, as a
cook lowers the handle to cradle the pancake) while lifted by :data:`LIFT`, then turned half
a turn about its own long axis (x) at :data:`FLIP_RATE`, which throws the pancake over, and
held while the pancake falls and settles. The spatula is moved kinematically: a fixed
constraint pulls it to the commanded pose at every control step (no arm is simulated).

Nothing in the program looks at the outcome; the same motion runs for every angle but the
blade's tilt during the push. Whether the pancake turns is physics: the tilted blade is a
wedge moving under the pancake's round rim, and its top face pushes the pancake forward as
well as up, the more the steeper it is (normal force along ``(sin angle, cos angle)``),
against the pancake's friction on the maker. A flat blade slides under a pancake that stays
nearly in place; a steep one gives it a forward speed the blade's friction cannot take out
before the blade stops, so it slides off the blade's front edge while the blade is levelled
and lifted, and the flip throws nothing over (with the knowledge base's values and the
program's physics settings, ``programs.turn_pancake`` in config/physics.yaml, the change
lies between 0.4 and 0.5 rad).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.geometry import quaternion_of
from projection_server.simulation.programs.registry import Parameter, Program, register

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Scenario

__all__ = ['PROGRAM', 'TurnPancake']

SETTLE = 0.3             # s for the pancake to settle before the spatula moves
CLEARANCE = 0.0005       # m between the blade's front edge and the maker's top
START_GAP = 0.01         # m between the blade's front edge and the pancake's rim at start
PUSH_SPEED = 0.5         # m/s along +x (average; a quick push, as a cook's)
REACH = 0.9              # front edge ends this fraction of the pancake's radius past its centre
LEVEL_TIME = 0.15        # s to turn the blade to CARRY_PITCH while lifting it
LIFT = 0.08              # m
FLIP_RATE = 10.0         # rad/s about the blade's long axis
AFTER = 1.0              # s for the pancake to fall and settle
CARRY_PITCH = -0.3       # rad: the blade's front edge up while lifting, to hold the pancake
HOLD_FORCE = 500.0       # N, maximal force of the constraint that moves the spatula
HOLD_RATE = 48.0         # 1/s of its error the constraint corrects (0.2 per step at 240 Hz)


def _ry(theta: float) -> np.ndarray:
    s, c = math.sin(theta), math.cos(theta)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rx(theta: float) -> np.ndarray:
    s, c = math.sin(theta), math.cos(theta)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


class TurnPancake:
    """The task: turn the scenario's first pancake with its first spatula."""

    def __init__(self, physics: Physics, scenario: Scenario, params: dict[str, float],
                 rng: np.random.Generator):
        spatula = next(scenario.of_class('spatula'), None)
        pancake = next(scenario.of_class('pancake'), None) or next(
            (e for e in scenario.of_class('particle_fluid')
             if e.properties.get('positions') is not None), None)
        maker = next(scenario.of_class('pancake_maker'), None)
        if spatula is None or pancake is None or maker is None:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  'turn_pancake needs a spatula, a pancake (or batter placed '
                                  'by positions) and a pancake_maker')
        c = physics.client
        self._client, self._spatula = c, physics.body(spatula.name).body_id
        robot = next(scenario.of_class('robot'), None)
        self._physics, self._robot = physics, (robot.name if robot else None)
        self._tool, self._object = spatula.name, pancake.name
        self.angle = params['angle']
        p = spatula.properties
        # The front edge's bottom, in the blade's frame.
        self._edge = np.array([p['size_x'] / 2, 0.0, -p['size_z'] / 2])
        if pancake.cls == 'pancake':
            px, py, _ = pancake.pose.xyz
            radius = pancake.properties['radius']
        else:
            xy = np.asarray(pancake.properties['positions'], dtype=float)[:, :2]
            px, py = xy.mean(axis=0)
            radius = (float(np.hypot(*(xy - (px, py)).T).max())
                      + pancake.properties['particle_radius'])
        top = maker.pose.xyz[2] + maker.properties['height'] / 2
        self._start = np.array([px - radius - START_GAP, py, top + CLEARANCE])
        self._end = np.array([px + REACH * radius, py, top + CLEARANCE])
        self.pushed = SETTLE + (self._end[0] - self._start[0]) / PUSH_SPEED
        self.levelled = self.pushed + LEVEL_TIME
        self.flipped = self.levelled + math.pi / FLIP_RATE
        self.duration = self.flipped + AFTER
        centre, quat = self.pose(0.0)
        c.resetBasePositionAndOrientation(self._spatula, centre, quat)
        self._constraint = c.createConstraint(
            self._spatula, -1, -1, -1, c.JOINT_FIXED, (0, 0, 0), (0, 0, 0), centre)
        # PyBullet gives a multibody's fixed constraint the engine's erp (0.2 a step), not
        # this one: the blade trails its path by up to 22 / 16 / 13 mm at 240 / 480 / 960 Hz.
        # A blade kept on its path makes Table III differ between these steps, where this one
        # gives the paper's at all three (bench/RESULTS.md, 2026-11-28, bench/spatula_lag.py).
        self._erp = min(1.0, HOLD_RATE / physics.settings.physics.rate_hz)
        c.changeConstraint(self._constraint, centre, quat, maxForce=HOLD_FORCE, erp=self._erp)

    def pose(self, t: float) -> tuple[np.ndarray, tuple[float, ...]]:
        """Commanded position of the blade's centre and orientation at time ``t`` [s]."""
        if t <= self.pushed:
            s = min(max((t - SETTLE) / (self.pushed - SETTLE), 0.0), 1.0)
            s = (1.0 - math.cos(math.pi * s)) / 2   # smooth start and stop
            edge = self._start + s * (self._end - self._start)
            rotation = _ry(self.angle)
        elif t <= self.levelled:
            s = (t - self.pushed) / LEVEL_TIME
            edge = self._end + np.array([0.0, 0.0, s * LIFT])
            rotation = _ry(self.angle + s * (CARRY_PITCH - self.angle))
        else:
            edge = self._end + np.array([0.0, 0.0, LIFT])
            roll = min((t - self.levelled) * FLIP_RATE, math.pi)
            # Turn about the blade's long axis through its centre (the level blade's centre
            # is at the front edge's height plus half its thickness, half its length back).
            axis = edge - np.array([self._edge[0], 0.0, self._edge[2]])
            rotation = _rx(roll) @ _ry(CARRY_PITCH)
            return axis, quaternion_of(rotation)
        return edge - rotation @ self._edge, quaternion_of(rotation)

    def control(self, physics: Physics) -> None:
        centre, quat = self.pose(physics.time)
        self._client.changeConstraint(self._constraint, centre, quat, maxForce=HOLD_FORCE,
                                      erp=self._erp)


    def state(self) -> list[tuple[str, int, str, str]]:
        """``(robot, -1, phase, target)`` of the scenario's first robot (none without one):
        ``settle`` with the spatula as target, then ``push``, ``lift``, ``flip`` and ``rest``
        with the pancake."""
        if self._robot is None:
            return []
        t = self._physics.time
        if t < SETTLE:
            return [(self._robot, -1, 'settle', self._tool)]
        phases = (('push', self.pushed), ('lift', self.levelled), ('flip', self.flipped))
        phase = next((name for name, end in phases if t < end), 'rest')
        return [(self._robot, -1, phase, self._object)]


PROGRAM = register(Program(
    name='turn_pancake',
    params=(
        Parameter('angle', 'rad', 0.0, 1.2, 0.3,
                  "the spatula blade's tilt to the horizontal while it is pushed under the "
                  'pancake (paper: 0.1-0.9)'),
    ),
    create=TurnPancake,
    doc=__doc__.splitlines()[0],
))
