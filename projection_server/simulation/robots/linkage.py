"""Grippers whose fingers turn: revolute finger joints, linkages of mimic joints.

A :class:`~projection_server.simulation.physics.Gripper` speaks of the *opening*, the gap
between its pads [m], and of the force each pad pushes with [N]. Revolute fingers are
driven by joint angles and torques instead; :class:`LinkageGripper` translates, from a
table of the opening against the fingers' common position ``u`` (0: every finger joint at
its closed value, 1: at its open value; a joint that mimics another follows it):

* the opening at ``u`` is the smallest distance between the pad links' collision shapes
  (PyBullet's closest points), measured once per robot in the kinematic copy
  (:func:`opening_table`, kept per process), so a linkage needs no geometry of its own;
* a finger joint's *lever* at ``u`` is how fast its pad moves along the gap per radian,
  ``|dO/du| / (n |open - closed|)`` for ``n`` finger joints sharing the gap (by virtual
  work, a drive of torque ``t`` pushes its pad, and through its mimic joints' gears the
  other pad, with ``t / lever``, wherever the pads are closest);
* ``close(F)`` turns each finger joint towards closed with a velocity motor whose torque is
  at most ``F`` times its lever at the fingers' position; while closing and holding, the
  limit follows the lever as the fingers move (re-set when ``u`` has changed by
  :data:`LEVER_STEP`), so each pad pushes with at most ``F``;
* ``open(o)`` puts the fingers at the ``u`` of opening ``o`` by position control;
  speeds are the pads' [m/s], as for prismatic fingers;
* while closing and holding, the finger links' weight is carried by the drive, as a real
  gripper's non-backdrivable drive carries it (an upward force on each at its centre of
  mass, every physics step; open, position control holds the fingers): hanging
  fingers would otherwise swing in on what they hold like pendulums (the KUKA SDF's
  fingers weigh 0.6 kg each, which at its pads is about 0.7 N more than asked for).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from projection_server.simulation.physics import Gripper

__all__ = ['LEVER_STEP', 'LinkageGripper', 'OpeningTable', 'TABLE_POINTS',
           'cached_opening_table', 'finger_values', 'gap', 'opening_table']

TABLE_POINTS = 41   # values of u at which the opening is measured
LEVER_STEP = 0.01   # change of u after which a closing motor's torque limit is set anew
MIN_LEVER = 1e-3    # m/rad: a lever below this (a linkage at a dead point) counts as this

_TABLES: dict[Any, tuple[list[float], list[float]]] = {}


class OpeningTable:
    """An opening table of :func:`opening_table` (``table``: ``u`` values, openings) with
    the finger joints' ``open`` and ``closed`` values: what every engine's linkage gripper
    translates its commands and readings with."""

    def __init__(self, open_values: Sequence[float], closed_values: Sequence[float],
                 table: tuple[Sequence[float], Sequence[float]]):
        self.open = np.asarray(open_values, float)
        self.closed = np.asarray(closed_values, float)
        self.span = self.open - self.closed
        self.u, self.openings = np.asarray(table[0], float), np.asarray(table[1], float)
        # dO/du at the middle of each interval of the table
        slopes = np.diff(self.openings) / np.diff(self.u)
        self.slope_u = (self.u[:-1] + self.u[1:]) / 2
        self.slopes = np.maximum(np.abs(slopes), 1e-9)
        self.mean_slope = max((self.openings[-1] - self.openings[0])
                              / (self.u[-1] - self.u[0]), 1e-9)
        self.max_opening = float(self.openings[-1])

    def levers(self, u: float) -> np.ndarray:
        """Each finger joint's lever at ``u`` [m/rad]: its pad's speed per joint speed."""
        slope = float(np.interp(u, self.slope_u, self.slopes))
        return np.maximum(slope / (len(self.span) * np.abs(self.span)), MIN_LEVER)

    def opening_at(self, u: float) -> float:
        """The opening [m] with the fingers at ``u``."""
        return float(np.interp(u, self.u, self.openings))

    def position_at(self, opening: float) -> float:
        """The fingers' ``u`` of ``opening`` [m] (at most the widest)."""
        return float(np.interp(min(opening, self.max_opening), self.openings, self.u))

    def rate(self, speed: float) -> float:
        """How fast ``u`` changes for the gap to close or open at ``2 speed`` [m/s] on
        average."""
        return 2 * speed / self.mean_slope


class LinkageGripper(Gripper):
    """A gripper of revolute finger joints ``fingers`` (their ``open`` and ``closed``
    values), with the opening table ``table`` (``u`` values, openings) of
    :func:`opening_table`; ``max_joint_torques`` limit the joints' motors when opening.
    ``finger_links`` are the pads' links (what touches a grasped object); ``carried`` the
    links that move with the fingers, whose weight the drive carries."""

    def __init__(self, client: Any, name: str, body_id: int, fingers: Sequence[int],
                 open_values: Sequence[float], closed_values: Sequence[float],
                 table: tuple[Sequence[float], Sequence[float]],
                 max_joint_torques: Sequence[float], max_force: float,
                 position_gain: float, finger_links: Sequence[str],
                 carried: Sequence[int] = ()):
        self._table = OpeningTable(open_values, closed_values, table)
        super().__init__(client, name, body_id, {'fingers': list(fingers)}, [],
                         max_joint_force=max(max_joint_torques), max_force=max_force,
                         max_opening=self._table.max_opening, position_gain=position_gain,
                         finger_links=list(finger_links))
        self._torques = list(max_joint_torques)
        self._scale = [(float(c), 1.0 / float(k))
                       for c, k in zip(self._table.closed, self._table.span)]
        self._set_at: float | None = None   # u at which the closing torques were set
        self._speed = 0.0
        self._carried = list(carried)
        self._weights: list[tuple[float, float, float]] | None = None   # set at first step

    # --- the table ------------------------------------------------------------------------
    def position(self) -> float:
        """The fingers' common position ``u`` (their mean)."""
        # plain floats: it runs every physics step while the gripper closes or holds
        states = self._client.getJointStates(self.body_id, self._fingers)
        return sum((s[0] - c) * k for s, (c, k) in zip(states, self._scale)) / len(states)

    def levers(self, u: float) -> np.ndarray:
        """Each finger joint's lever at ``u`` [m/rad]: its pad's speed per joint speed."""
        return self._table.levers(u)

    # --- commands -------------------------------------------------------------------------
    def close(self, force: float, speed: float) -> None:
        force = min(force, self.max_force)
        self.command, self.commanded_force = 'close', force
        self._speed = speed
        self._set_closing(self.position())

    def _set_closing(self, u: float) -> None:
        levers = self.levers(u)
        rate = self._table.rate(self._speed)   # the fingers' u falls at this rate
        c = self._client
        for joint, span, lever in zip(self._fingers, self._table.span, levers):
            c.setJointMotorControl2(self.body_id, joint, c.VELOCITY_CONTROL,
                                    targetVelocity=-rate * span,
                                    force=self.commanded_force * float(lever))
        self._set_at = u

    def after_step(self) -> None:
        """After a physics step, for the next, while the fingers close or hold (open, they
        are held by position control): the finger links' weight carried; the closing
        motors' torque limits follow the lever."""
        if self.command != 'close':
            return
        c = self._client
        if self._carried:
            if self._weights is None:
                params = c.getPhysicsEngineParameters()
                g = [params[f'gravityAcceleration{a}'] for a in 'XYZ']
                self._weights = [tuple(-c.getDynamicsInfo(self.body_id, link)[0] * v
                                       for v in g) for link in self._carried]
            body, push, world = self.body_id, c.applyExternalForce, c.WORLD_FRAME
            states = c.getLinkStates(body, self._carried)
            for link, state, lift in zip(self._carried, states, self._weights):
                push(body, link, lift, state[0], world)
        u = self.position()
        if abs(u - self._set_at) >= LEVER_STEP:
            self._set_closing(u)

    def open(self, opening: float, speed: float) -> None:
        self.command, self.commanded_force = 'open', 0.0
        u = self._table.position_at(opening)
        rate = self._table.rate(speed)
        c = self._client
        table = self._table
        for joint, closed, span, torque in zip(self._fingers, table.closed, table.span,
                                               self._torques):
            c.setJointMotorControl2(self.body_id, joint, c.POSITION_CONTROL,
                                    targetPosition=float(closed + u * span),
                                    maxVelocity=rate * abs(float(span)), force=torque,
                                    positionGain=self._gain)

    def state(self) -> tuple[float, float]:
        """``(opening, measured force)``: the opening at the fingers' position; the mean
        pad force of the finger motors' torques through their levers."""
        joints = self._client.getJointStates(self.body_id, self._fingers)
        table = self._table
        u = float(np.mean((np.asarray([j[0] for j in joints]) - table.closed) / table.span))
        forces = np.abs([j[3] for j in joints]) / self.levers(u)
        return table.opening_at(u), float(forces.mean())


def gap(client: Any, body: int, values: dict[int, float], pads: Sequence[int]) -> float:
    """The smallest distance between the collision shapes of the links ``pads`` of
    ``body`` (a robot before its world runs, or a kinematic copy) with its joints reset to
    ``values`` [m] (negative: they overlap; nan: they are more than 1 m apart or have no
    shapes)."""
    for joint, value in values.items():
        client.resetJointState(body, joint, value)
    distances = [p[8] for i, a in enumerate(pads) for b in pads[i + 1:]
                 for p in client.getClosestPoints(body, body, 1.0, a, b)]
    return min(distances) if distances else math.nan


def finger_values(fingers: Sequence[int], open_values: Sequence[float],
                  closed_values: Sequence[float], mimics: dict[int, tuple[int, float, float]],
                  held: dict[int, float], u: float) -> dict[int, float]:
    """The joints' values with the fingers at ``u``: ``mimics`` (joint -> the joint it
    follows, multiplier, offset) following them, ``held`` joints at their values."""
    values = dict(held)
    for joint, o, c in zip(fingers, open_values, closed_values):
        values[joint] = c + u * (o - c)
    for _ in range(2):   # a joint may mimic one that mimics
        for joint, (parent, multiplier, offset) in mimics.items():
            values[joint] = values.get(parent, 0.0) * multiplier + offset
    return values


def opening_table(client: Any, body: int, fingers: Sequence[int],
                  open_values: Sequence[float], closed_values: Sequence[float],
                  mimics: dict[int, tuple[int, float, float]], held: dict[int, float],
                  pads: Sequence[int]) -> tuple[list[float], list[float]]:
    """The opening (:func:`gap`, never below 0) at :data:`TABLE_POINTS` values of ``u``
    from 0 to 1 in the kinematic copy ``body`` of ``client`` (see :func:`finger_values`).
    The openings are made to grow with ``u`` (a linkage that folds back past its widest
    is taken as widest)."""
    us = np.linspace(0.0, 1.0, TABLE_POINTS)
    openings = [gap(client, body, finger_values(fingers, open_values, closed_values, mimics,
                                                held, float(u)), pads) for u in us]
    openings = np.maximum(np.nan_to_num(openings), 0.0)
    return us.tolist(), np.maximum.accumulate(openings).tolist()


def cached_opening_table(key: Any, *args: Any) -> tuple[list[float], list[float]]:
    """:func:`opening_table` of ``args``, made once per process for the robot ``key``
    (its model file and gripper facts: the table depends on nothing else)."""
    table = _TABLES.get(key)
    if table is None:
        table = _TABLES[key] = opening_table(*args)
    return table
