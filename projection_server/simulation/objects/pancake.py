"""``pancake``: a deformable body of jointed segments (Kunze et al. 2011, sec. IV-C, Fig. 7).

A pancake is one PyBullet multibody: a tree of flat *segments* joined by spherical joints.
The root segment is the multibody's base, every other segment a link whose parent is the
segment it is joined to, its link frame at the joint's pivot (half way between the two
segments' centres). Segments do not collide with each other.

Two layouts (the scenario's ``model``):

* ``"rings"``, the paper's generic circular model: a centre disc and ``ring_count`` rings
  of ``segment_count`` segments each. With ``d = radius / (ring_count + 0.5)`` the centre
  disc has radius ``d / 2`` and ring ``k`` covers radii ``(k - 1/2) d .. (k + 1/2) d``;
  segment ``(k, j)`` spans ``d`` radially and its arc tangentially, joined to segment
  ``(k - 1, j)`` (ring 1 to the centre disc). Its collision shape is two capsules of the
  pancake's thickness along its inner and outer edge (the centre disc: two across it):
  every edge of a pancake is round, which is what lets a spatula's thin blade get under it
  rather than only push against it (a box's square edge only gets pushed).
* ``"particles"``, built by the knowledge base's object model factory from poured particles:
  one sphere (diameter = ``thickness``) per offset of ``particles``, joined along
  ``joints`` (``[parent, child]`` pairs of a tree, parent < child; index 0 is the seed).
  Beyond :data:`MAX_SEGMENTS` particles, connected groups of them form one segment each
  (:func:`particles_layout`).

The joints are angular springs (:class:`PancakeSprings`): before every physics step each
joint's servo towards the flat rest shape may apply at most ``joint_stiffness * angle +
joint_damping * angular speed``. The constraint solver applies that bounded torque
implicitly, so the stiff springs of the knowledge base (0.05 N m/rad on segments of a few
grams) stay stable at Bullet's 240 Hz where explicit spring torques would not. Masses are
shared out by segment area (rings) or by particles (particles).

Orientation reference: the two segments named :data:`REFERENCE_LINKS` lie on the rim (rings:
ring ``ring_count`` at angle 0 and a quarter turn further; particles: the segment whose
joint is farthest from the seed and the one most nearly a quarter turn from it,
counter-clockwise seen from above), so that ``(a - c) x (b - c)`` with ``c`` the root's position is the pancake's upper
side normal (see :mod:`projection_server.timeline.turning`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
import math
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.bags import REFERENCE_LINKS
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.objects.common import compound_shape, MAX_COMPOUND_SHAPES
from projection_server.simulation.objects.registry import (FRACTION, NAME, NONNEGATIVE,
                                                           ObjectClass, PAIRS, POINTS,
                                                           POSITIVE, Property, register,
                                                           REQUIRED)
from projection_server.simulation.physics import Body, Shape

if TYPE_CHECKING:
    from projection_server.simulation.physics import Physics
    from projection_server.simulation.scenario import Entity

__all__ = ['MAX_SEGMENTS', 'PANCAKE', 'PancakeSprings', 'REFERENCE_LINKS', 'Segment',
           'build_pancake',
           'particles_layout', 'rings_layout']

COLOR = (0.85, 0.65, 0.3, 1.0)
SELF_GROUP = 0x100        # collision group bit of pancake segments (they skip each other;
#                           Bullet uses 1 and 2 for dynamic and static bodies)
MAX_SEGMENTS = 32         # base + 31 spherical joints: what PyBullet reports states of
SERVO_RATE = 72.0         # 1/s the joint servos correct of their error (0.3 per step at 240 Hz;
                          # the torque bound is the spring)


@dataclass(frozen=True)
class Segment:
    """One segment, in the pancake's frame: centre, parent segment (-1: root), joint pivot,
    collision ``(kind, size, yaw)`` and area (for the mass share)."""

    centre: tuple[float, float, float]
    parent: int
    pivot: tuple[float, float, float]
    kind: str                         # 'disc', 'ring', 'sphere'
    size: tuple[float, float, float]  # extents: radial, tangential, thickness
    yaw: float
    area: float
    name: str
    spheres: tuple[tuple[float, float, float], ...] = ()   # 'sphere': one per particle


def rings_layout(radius: float, thickness: float, ring_count: int,
                 segment_count: int) -> list[Segment]:
    """The generic circular model: centre disc first, then ring by ring."""
    d = radius / (ring_count + 0.5)
    out = [Segment((0.0, 0.0, 0.0), -1, (0.0, 0.0, 0.0), 'disc', (d, d, thickness), 0.0,
                   math.pi * d * d / 4, 'centre')]
    for k in range(1, ring_count + 1):
        arc = 2 * math.pi * k * d / segment_count
        for j in range(segment_count):
            phi = 2 * math.pi * j / segment_count
            u = (math.cos(phi), math.sin(phi))
            centre = (k * d * u[0], k * d * u[1], 0.0)
            pivot = ((k - 0.5) * d * u[0], (k - 0.5) * d * u[1], 0.0)
            parent = 0 if k == 1 else 1 + (k - 2) * segment_count + j
            name = f'ring{k}_{j}'
            if k == ring_count and j == 0:
                name = REFERENCE_LINKS[0]
            elif k == ring_count and 4 * j == segment_count:
                name = REFERENCE_LINKS[1]
            out.append(Segment(centre, parent, pivot, 'ring',
                               (d, arc, thickness), phi, d * arc, name))
    return out


def particles_layout(particles: list[Any], joints: list[Any], thickness: float,
                     max_segments: int = MAX_SEGMENTS) -> list[Segment]:
    """One segment per particle offset, joined along the tree of ``joints``.

    PyBullet reports the joint states of at most :data:`MAX_SEGMENTS` - 1 spherical joints of
    one multibody, fewer than the particles a pour leaves on the pan. Beyond that many, the
    tree is contracted: the smallest segment is merged with the smallest one it is joined to
    until few enough remain, so a segment is a connected group of particles of about equal
    size (one sphere each); the factory's joints inside a group become rigid, the others stay
    springs. A group is one compound, so it holds at most :data:`MAX_COMPOUND_SHAPES`
    particles. Where merging leaves too many groups (small ones between full ones), the tree
    is cut into the fewest connected groups within that cap instead; a pancake that no cut
    fits (more than ``max_segments`` x 16 particles, or a tree too branched) is refused
    (``invalid_scenario``) rather than built with joints PyBullet does not report.
    """
    points = np.asarray(particles, dtype=float).reshape(-1, 3)
    n = len(points)
    parents = [-1] * n
    for parent, child in joints:
        if not 0 <= parent < child < n or parents[child] != -1:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'pancake joints must form a tree with parent < child, '
                                  f'got {[parent, child]}')
        parents[child] = parent
    if n == 0 or any(p == -1 for p in parents[1:]):
        raise ProjectionError(ErrorKind.INVALID_SCENARIO, 'every pancake particle but the seed '
                                                  'needs a parent joint')
    head = list(range(n))             # each particle's segment, named by its first particle
    full = set()                      # segments that no neighbour can join
    while len(set(head)) > max_segments:
        size = Counter(head)
        open_ = [h for h in size if h not in full]
        if not open_:
            break             # cut or refused below
        # The smallest segment (the last joined on a tie: the rim first) joins the smallest
        # segment it shares a joint with; the union's first particle names it. A segment is
        # one compound of a sphere per particle, so a union stays within what PyBullet keeps.
        small = min(open_, key=lambda h: (size[h], -h))
        touching = {head[j] for i in range(1, n) for j in (i, parents[i])
                    if small in (head[i], head[parents[i]])} - {small}
        fits = [h for h in touching if size[h] + size[small] <= MAX_COMPOUND_SHAPES]
        if not fits:
            full.add(small)
            continue
        other = min(fits, key=lambda h: (size[h], -h))
        keep, drop = min(small, other), max(small, other)
        head = [keep if h == drop else h for h in head]
    if len(set(head)) > max_segments:
        # Merging the smallest left small groups between full ones: cut the tree into the
        # fewest connected groups instead (Kundu and Misra's greedy), with the smallest cap
        # that gives few enough, so the groups stay about equal.
        head = next((h for cap in range(2, MAX_COMPOUND_SHAPES + 1)
                     if len(set(h := _tree_groups(parents, cap))) <= max_segments), head)
    if len(set(head)) > max_segments:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'a pancake of {n} particles needs {len(set(head))} groups of at '
                              f'most {MAX_COMPOUND_SHAPES}; a multibody reports {max_segments}')
    heads = sorted(set(head))         # ascending: a parent segment before its children
    index = {h: k for k, h in enumerate(heads)}
    members: dict[int, list[int]] = {h: [] for h in heads}
    for i in range(n):
        members[head[i]].append(i)
    pivots = [points[0]] + [(points[h] + points[parents[h]]) / 2 for h in heads[1:]]
    rel = np.asarray(pivots) - points[0]
    names = [f'p{h}' for h in heads]
    names[0] = 'centre'
    if len(heads) >= 3:
        a = int(np.argmax(np.linalg.norm(rel[:, :2], axis=1)))
        angle = np.arctan2(rel[:, 1], rel[:, 0]) - math.atan2(rel[a, 1], rel[a, 0])
        score = -np.abs(np.mod(angle, 2 * math.pi) - math.pi / 2)
        score[[0, a]] = -np.inf
        b = int(np.argmax(score))
        names[a], names[b] = REFERENCE_LINKS
    area = math.pi * thickness * thickness / 4
    return [Segment(tuple(points[members[h]].mean(axis=0)),
                    index[head[parents[h]]] if h else -1, tuple(pivots[k]), 'sphere',
                    (thickness,) * 3, 0.0, area * len(members[h]), names[k],
                    tuple(tuple(points[i]) for i in members[h]))
            for k, h in enumerate(heads)]


def _tree_groups(parents: list[int], cap: int) -> list[int]:
    """The fewest connected groups of at most ``cap`` nodes of the tree ``parents``
    (parent < child), each node's group named by its topmost node."""
    n = len(parents)
    weight = [1] * n
    children: list[list[int]] = [[] for _ in range(n)]
    cut = [False] * n
    for i in range(n - 1, -1, -1):     # children before their parent
        for child in sorted(children[i], key=lambda c: weight[c]):   # lightest kept
            if weight[i] + weight[child] > cap:
                cut[child] = True
            else:
                weight[i] += weight[child]
        if i:
            children[parents[i]].append(i)
    head = list(range(n))
    for i in range(1, n):
        if not cut[i]:
            head[i] = head[parents[i]]
    return head


def build_pancake(physics: Physics, entity: Entity) -> None:
    """Build ``entity`` (class pancake) as a jointed multibody and attach its springs."""
    c, p = physics.client, entity.properties
    if p['model'] == 'rings':
        segments = rings_layout(p['radius'], p['thickness'], int(p['ring_count']),
                                int(p['segment_count']))
    elif p['model'] == 'particles':
        if p.get('particles') is None or p.get('joints') is None:
            raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                                  f'{entity.name}: model "particles" needs particles and joints')
        segments = particles_layout(p['particles'], p['joints'], p['thickness'])
    else:
        raise ProjectionError(ErrorKind.INVALID_SCENARIO,
                              f'{entity.name}: unknown pancake model {p["model"]!r}')
    total = sum(s.area for s in segments)
    masses = [p['mass'] * s.area / total for s in segments]
    root = segments[0]
    frames = [np.asarray(root.centre)] + [np.asarray(s.pivot) for s in segments[1:]]
    shapes = [_collision_shape(c, s, np.asarray(s.centre) - frames[i])
              for i, s in enumerate(segments)]
    links = segments[1:]
    rotation = np.asarray(c.getMatrixFromQuaternion(
        c.getQuaternionFromEuler(entity.pose.rpy))).reshape(3, 3)
    body_id = c.createMultiBody(
        masses[0], shapes[0], -1, np.asarray(entity.pose.xyz) + rotation @ frames[0],
        c.getQuaternionFromEuler(entity.pose.rpy),
        linkMasses=masses[1:], linkCollisionShapeIndices=shapes[1:],
        linkVisualShapeIndices=[-1] * len(links),
        linkPositions=[frames[i] - frames[s.parent] for i, s in enumerate(segments) if i],
        linkOrientations=[(0.0, 0.0, 0.0, 1.0)] * len(links),
        linkInertialFramePositions=[np.asarray(s.centre) - frames[i]
                                    for i, s in enumerate(segments) if i],
        linkInertialFrameOrientations=[(0.0, 0.0, 0.0, 1.0)] * len(links),
        linkParentIndices=[s.parent for s in links],   # 0: the base (segment 0)
        linkJointTypes=[c.JOINT_SPHERICAL] * len(links),
        linkJointAxis=[(0.0, 0.0, 1.0)] * len(links))
    for link in range(-1, len(links)):
        c.changeDynamics(body_id, link, lateralFriction=p['friction'],
                         restitution=p['restitution'], linearDamping=0.0, angularDamping=0.0)
        c.setCollisionFilterGroupMask(body_id, link, SELF_GROUP, 0x7FFFFFFF & ~SELF_GROUP)
    # PyBullet numbers the links depth first, not in the given order; the names it gives
    # them ("link<k>", k = 1 for the first given) keep the given order.
    segment = {-1: 0} | {j: int(c.getJointInfo(body_id, j)[12].decode()[len('link'):])
                         for j in range(c.getNumJoints(body_id))}
    # Markers in each segment's frame (-1: the base), so that they turn with the segment.
    link_shapes = {j: _marker_shapes(c, segments[k], frames[k]) for j, k in segment.items()}
    physics.add_body(Body(entity.name, entity.cls, body_id, False, None,
                          links={j: segments[k].name for j, k in segment.items() if j >= 0},
                          link_shapes=link_shapes))
    physics.models.append(PancakeSprings(entity.name, c, body_id, len(links),
                                         p['joint_stiffness'], p['joint_damping'],
                                         physics.settings.physics.rate_hz))


def _collision_shape(c: Any, s: Segment, offset: np.ndarray) -> int:
    radial, tangential, thickness = s.size
    if s.kind == 'sphere':
        shift = offset - np.asarray(s.centre)
        return compound_shape(
            c, [c.GEOM_SPHERE] * len(s.spheres), radii=[thickness / 2] * len(s.spheres),
            collisionFramePositions=[list(np.asarray(q) + shift) for q in s.spheres])
    # Rings and centre: capsules of the thickness along the segment's inner and outer edge
    # (the centre: two across it), so every edge a blade can meet is round.
    r = thickness / 2
    u = np.array([math.cos(s.yaw), math.sin(s.yaw), 0.0])
    if s.kind == 'disc':
        edges = [(offset + u * (radial / 4), radial - 2 * r), (offset - u * (radial / 4),
                                                                radial - 2 * r)]
    else:
        k = float(np.linalg.norm(s.centre[:2])) / radial   # the ring's number
        edges = [(offset + sign * u * (radial / 2 - r),
                  tangential * (k + sign * (0.5 - r / radial)) / k - 2 * r)
                 for sign in (-1.0, 1.0)]
    capsule = list(c.getQuaternionFromEuler((math.pi / 2, 0.0, s.yaw)))   # z -> tangent
    return compound_shape(
        c, [c.GEOM_CAPSULE] * 2, radii=[r, r], lengths=[max(length, 1e-4) for _, length in edges],
        collisionFramePositions=[list(e) for e, _ in edges],
        collisionFrameOrientations=[capsule, capsule])


def _marker_shapes(c: Any, s: Segment, frame: np.ndarray) -> list[tuple[Shape, tuple]]:
    """The segment as markers with their offsets from its frame: a sphere per particle, a
    box turned to the ring segment's direction, or the centre disc."""
    radial, tangential, thickness = s.size
    if s.kind == 'sphere':
        return [(Shape('sphere', s.size, COLOR), tuple(np.asarray(q) - frame))
                for q in s.spheres]
    offset = tuple(np.asarray(s.centre) - frame)
    if s.kind == 'disc':
        return [(Shape('cylinder', (radial, radial, thickness), COLOR), offset)]
    return [(Shape('box', s.size, COLOR, c.getQuaternionFromEuler((0.0, 0.0, s.yaw))),
             offset)]


class PancakeSprings:
    """The pancake's joints as angular springs (an object model, see the module doc).

    Each step the servo of every spherical joint targets the rest (flat) shape with a torque
    bound of ``stiffness * angle + damping * speed`` [N m], angle and angular speed of the
    joint. ``load`` is the largest spring torque of the last step [N m]; it never breaks.
    """

    def __init__(self, name: str, client: Any, body_id: int, joints: int, stiffness: float,
                 damping: float, rate_hz: float):
        self.name = name
        self._gain = min(1.0, SERVO_RATE / rate_hz)
        self.load = 0.0
        self._client, self._body = client, body_id
        self._joints = list(range(joints))
        self._k, self._c = stiffness, damping
        self.after_step(None)

    def after_step(self, physics: Physics | None) -> None:
        c = self._client
        if not self._joints:
            return
        states = c.getJointStatesMultiDof(self._body, self._joints)
        forces = []
        for quat, omega, *_ in states:
            angle = 2.0 * math.acos(min(1.0, abs(quat[3])))
            torque = self._k * angle + self._c * math.sqrt(sum(w * w for w in omega))
            forces.append([torque] * 3)
        self.load = max(f[0] for f in forces)
        c.setJointMotorControlMultiDofArray(
            self._body, self._joints, c.POSITION_CONTROL,
            targetPositions=[[0.0, 0.0, 0.0, 1.0]] * len(self._joints),
            targetVelocities=[[0.0, 0.0, 0.0]] * len(self._joints),
            positionGains=[self._gain] * len(self._joints),
            velocityGains=[1.0] * len(self._joints), forces=forces)

    def sample(self) -> tuple[float, float, bool]:
        return self.load, 0.0, False


PANCAKE = register(ObjectClass(
    name='pancake',
    properties=(
        Property('radius', REQUIRED, POSITIVE, 'm'),
        Property('thickness', REQUIRED, POSITIVE, 'm'),
        Property('mass', REQUIRED, POSITIVE, 'kg'),
        Property('friction', 0.5, NONNEGATIVE),
        Property('restitution', 0.0, FRACTION),
        # "rings" (a centre disc and rings of segments) or "particles" (one segment per
        # given offset): see the module doc.
        Property('model', 'rings', NAME),
        Property('joint_stiffness', 0.05, POSITIVE, 'N m/rad'),
        Property('joint_damping', 0.001, NONNEGATIVE, 'N m s/rad'),
        Property('joint_radius', 0.015, POSITIVE, 'm'),
        Property('ring_count', 3, POSITIVE),
        Property('segment_count', 8, POSITIVE),
        Property('particles', None, POINTS, 'm', 'offsets of the "particles" model'),
        Property('joints', None, PAIRS, '', '[parent, child] pairs of the "particles" model'),
    ),
    fixed={'shape': 'disc'},
    aliases={'diameter': ('radius', 0.5), 'height': ('thickness', 1.0)},
    build=build_pancake,
    doc=__doc__.splitlines()[0].strip('"'),
))
