"""``pour(angle, time, position)``: pour the pancake mix from the cup onto the pancake maker.

The cup, filled with the particle fluid it contains, is held upright above the pancake maker
at the height of its pose in the scenario, with its pouring lip (the rim on the
:data:`POUR_SIDE` of x) over the maker's centre shifted by ``position`` metres along y. It
tilts about the lip (so that its opening turns towards that side) at :data:`TILT_RATE` up to
``angle`` (0 = upright, pi/2 = on its side), holds that angle for ``time`` seconds, tilts
back upright at the same rate and the particles settle. It speeds up and slows down at
:data:`TILT_ACCEL`, so that it comes to rest at ``angle`` and upright rather than stopping at
once. The paper gives no rate; 1 rad/s is the second of the two coefficients fitted to its
Table II as a whole, beside the mix's surface tension (bench/batter_fit.py, bench/RESULTS.md
2026-11-28). While it tilts, the lip is lowered as far as the cup's lowest point keeps its
initial clearance above the maker, but not below :data:`POUR_HEIGHT` (a person pours batter
from a few centimetres above the pan). The cup is moved kinematically: a fixed constraint
pulls it to the commanded pose at every physics step (no arm is simulated), so that it moves
the same smooth path at every time step. Once the cup is upright again the pour ends as soon
as the batter has come to rest (every particle slower than :data:`REST_SPEED`), after
:data:`AFTER` seconds at the latest. Nothing in the program looks at where the batter is.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.programs.registry import Parameter, Program, register

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Scenario

__all__ = ['PROGRAM', 'Pour']

TILT_RATE = 1.0          # rad/s, tilting and tilting back (about 2 s to 2 rad: a careful pour)
TILT_ACCEL = 8.0         # rad/s^2, speeding up to TILT_RATE and slowing down from it
SETTLE = 0.3             # s for the fluid to settle in the upright cup before tilting
AFTER = 0.8              # s at most for the poured fluid to settle after the cup is upright
REST_SPEED = 0.01        # m/s: the batter is at rest when no particle moves faster
POUR_HEIGHT = 0.03       # m, lowest height of the lip above the maker's top while pouring
CUP_HOLD_FORCE = 500.0   # N, maximal force of the constraint that moves the cup
# The side of x the cup pours to: the paper's angle tilts the cup counterclockwise (Table
# II's note 3), as seen with x to the right and z up, so its opening turns towards -x, and its
# batter's centroid lies at negative x in 21 of the 26 pours that leave some on the pan.
POUR_SIDE = -1.0


class Pour:
    """The task: pour the scenario's first cup over its first pancake maker."""

    def __init__(self, physics: Physics, scenario: Scenario, params: dict[str, float],
                 rng: np.random.Generator):
        cup = next(scenario.of_class('cup'), None)
        maker = next(scenario.of_class('pancake_maker'), None)
        if cup is None or maker is None:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO, 'pour needs a cup and a pancake_maker')
        c = physics.client
        self._schedule(params)
        self._client, self._cup = c, physics.body(cup.name).body_id
        robot = next(scenario.of_class('robot'), None)
        self._robot, self._cup_name = (robot.name if robot else None), cup.name
        radius, height = cup.properties['radius'], cup.properties['height']
        start, _ = physics.pose(cup.name)
        mx, my, mz = maker.pose.xyz
        self._top = mz + maker.properties['height'] / 2
        # Keep the cup's height; put its lip over the maker's centre, shifted along y.
        self._centre = np.array([mx - POUR_SIDE * radius, my + params['position'], start[2]])
        self._lip = self._centre + np.array([POUR_SIDE * radius, 0.0, height / 2])
        self._clearance = start[2] - height / 2 - self._top   # of the upright cup's bottom
        # The rim and bottom of the cup in the plane of tilting, relative to the lip, as
        # seen with the opening turning towards +x (``lip_height`` is the same either side).
        self._corners = np.array([[0.0, 0.0], [-2 * radius, 0.0], [0.0, -height],
                                  [-2 * radius, -height]])   # (x, z)
        shift = self._centre - np.asarray(start)
        for fluid in physics.fluids.values():
            for body in fluid.body_ids:
                position, quat = c.getBasePositionAndOrientation(body)
                c.resetBasePositionAndOrientation(body, np.asarray(position) + shift, quat)
        physics.particles_moved()
        upright = c.getQuaternionFromEuler((0.0, 0.0, 0.0))
        c.resetBasePositionAndOrientation(self._cup, self._centre, upright)
        self._constraint = c.createConstraint(
            self._cup, -1, -1, -1, c.JOINT_FIXED, (0, 0, 0), (0, 0, 0), self._centre)
        c.changeConstraint(self._constraint, self._centre, upright, maxForce=CUP_HOLD_FORCE)
        # The constraint corrects the fraction erp of its error per physics step, so it
        # trails a moving target by (1 - erp) / erp steps: each step it is given the pose
        # that far ahead of the next step's, and the cup follows the commanded path itself
        # (a target moved only at control steps made the cup jerk at the control rate, and
        # the more so the finer the step: the batter was shaken out of it).
        engine = physics.settings.physics
        self._lead = engine.time_step * (1.0 + (1.0 - engine.erp) / max(engine.erp, 1e-3))
        self._physics = physics
        self._half_height = height / 2
        self._particles = [b for fluid in physics.fluids.values() for b in fluid.body_ids]
        physics.step_hooks.append(self._follow)

    def _schedule(self, params: dict[str, float]) -> None:
        self.angle, self.hold = params['angle'], params['time']
        self.tilted = SETTLE + tilt_duration(self.angle)
        self.released = self.tilted + self.hold
        self.upright = self.released + tilt_duration(self.angle)
        self.duration = self.upright + AFTER

    def tilt(self, t: float) -> float:
        """Commanded tilt angle [rad] at time ``t`` [s]."""
        return tilt(self.angle, self.hold, t)

    def command_at(self, params: dict[str, float], step: int) -> float:
        """The tilt that ``params`` command for the step after ``step`` (see ``_follow``)."""
        return tilt(params['angle'], params['time'],
                    step / self._physics.settings.physics.rate_hz + self._lead)

    def retarget(self, params: dict[str, float]) -> None:
        """Go on with the angle and time of ``params`` from the current step."""
        self._schedule(params)
        self._follow()

    def lip_height(self, theta: float) -> float:
        """Height [m] of the lip above the maker's top at tilt ``theta``: the cup's lowest
        point keeps the upright cup's clearance, the lip stays at least at POUR_HEIGHT."""
        s, co = math.sin(theta), math.cos(theta)
        lowest = float(np.min(-s * self._corners[:, 0] + co * self._corners[:, 1]))
        return max(POUR_HEIGHT, self._clearance - lowest)

    def control(self, physics: Physics) -> None:
        if physics.step_count == 0:
            self._command(self._lead)

    def finished(self, physics: Physics) -> bool:
        """Whether the pour is over: the cup is upright again and the batter that left it
        (below the cup's bottom) has come to rest."""
        if physics.time < self.upright:
            return False
        c = self._client
        bottom = c.getBasePositionAndOrientation(self._cup)[0][2] - self._half_height
        for body in self._particles:
            if (c.getBasePositionAndOrientation(body)[0][2] < bottom
                    and math.hypot(*c.getBaseVelocity(body)[0]) >= REST_SPEED):
                return False
        return True

    def state(self) -> list[tuple[str, int, str, str]]:
        """``(robot, -1, phase, cup)`` of the scenario's first robot (none without one):
        the phase under way, ``settle``, ``tilt``, ``hold``, ``tilt_back`` or ``rest``."""
        if self._robot is None:
            return []
        t = self._physics.time
        phases = (('settle', SETTLE), ('tilt', self.tilted), ('hold', self.released),
                  ('tilt_back', self.upright))
        phase = next((name for name, end in phases if t < end), 'rest')
        return [(self._robot, -1, phase, self._cup_name)]

    def _follow(self) -> None:
        self._command(self._physics.time + self._lead)

    def _command(self, t: float) -> None:
        theta = self.tilt(t)
        pitch = POUR_SIDE * theta   # about +y: a positive pitch turns the opening to +x
        s, co = math.sin(pitch), math.cos(pitch)
        rotation = np.array([[co, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, co]])
        lip = self._lip.copy()
        lip[2] = self._top + min(self.lip_height(theta), self._lip[2] - self._top)
        centre = lip + rotation @ (self._centre - self._lip)
        self._client.changeConstraint(
            self._constraint, centre, self._client.getQuaternionFromEuler((0.0, pitch, 0.0)),
            maxForce=CUP_HOLD_FORCE)


def tilt_duration(angle: float) -> float:
    """Seconds to tilt by ``angle`` [rad] from rest to rest."""
    if angle <= TILT_RATE ** 2 / TILT_ACCEL:   # too short to reach TILT_RATE
        return 2.0 * math.sqrt(angle / TILT_ACCEL)
    return angle / TILT_RATE + TILT_RATE / TILT_ACCEL


def tilted_by(angle: float, s: float) -> float:
    """The angle [rad] turned ``s`` seconds into a tilt by ``angle`` from rest to rest: speed
    up at TILT_ACCEL to at most TILT_RATE, go on, and slow down at TILT_ACCEL to stop at
    ``angle`` (a cup stopped or turned back at once jerks the batter at its lip)."""
    total = tilt_duration(angle)
    if s <= 0.0:
        return 0.0
    if s >= total:
        return angle
    ramp = min(TILT_RATE, TILT_ACCEL * total / 2) / TILT_ACCEL
    if s <= ramp:
        return TILT_ACCEL * s * s / 2
    if s <= total - ramp:
        return TILT_ACCEL * ramp * (s - ramp / 2)
    left = total - s
    return angle - TILT_ACCEL * left * left / 2


def tilt(angle: float, hold: float, t: float) -> float:
    """The tilt [rad] commanded at time ``t`` [s] of a pour to ``angle`` held ``hold`` s."""
    if t <= SETTLE:
        return 0.0
    tilted = SETTLE + tilt_duration(angle)
    if t <= tilted:
        return tilted_by(angle, t - SETTLE)
    if t <= tilted + hold:
        return angle
    return angle - tilted_by(angle, t - tilted - hold)


PROGRAM = register(Program(
    name='pour',
    params=(
        Parameter('angle', 'rad', 0.0, math.pi, 1.99,
                  "the cup's tilt from upright at which it is held (paper: 1.84-2.14)"),
        Parameter('time', 's', 0.0, 3.0, 0.5, 'how long the cup is held at that angle'),
        Parameter('position', 'm', -0.15, 0.15, 0.0,
                  "the cup's offset from the pancake maker's centre along y"),
    ),
    create=Pour,
    doc=__doc__.splitlines()[0],
    setup_params=('position',),   # where the cup is put; angle and time act by tilting
))
