"""Translation of a projection's records into a timeline of fluents, events and quantities.

``translate_records(records, bag, scenario)`` returns the dict of ``docs/contracts.md``,
from what the monitor logged (:class:`~projection_server.bags.Record` s, the worker's own
or read back from a bag: :func:`projection_server.workers.run.translate_bag`) and the
projection's checked scenario. Every monitoring sample
(one ``ContactArray``, ``/tf``, ``GripperState``, ``ObjectStateArray`` and ``TaskState`` per
step) gives a truth value of each fluent; fluents hold on maximal intervals of true samples,
with gaps shorter than ``timeline.gap_merge`` merged; events are read off those intervals.
The thresholds are the ``timeline`` settings recorded in the bag itself, all in physical
units (see ``config/physics.yaml``; a setting a bag predates has the settings file's value).
A sample's contacts are those of every physics step since the previous sample. Robots are
the driven bodies (their links are logged as a chain under them); a robot's contacts name
its links, its base link by ``''``. Bodies are the moving bodies (on ``/tf``) but robots and
particle fluids; link frames (``body/link``) are not bodies. The translation has three
stages: :mod:`~projection_server.timeline.samples` makes the samples of the records,
:mod:`~projection_server.timeline.rules` reads the fluents, events and quantities of bodies
off them, and :mod:`~projection_server.timeline.fluids` those of particle fluids.

Fluents (arguments are entity names):

* ``contact(A, B)``: A and B touch with at least ``contact_force_min``; A < B by name.
* ``supported_by(A, B)``: A touches B (not a gripper) and the contact normal, from B to A,
  is within ``support_max_angle`` of straight up.
* ``in_gripper(O)``: O touches every finger link of a gripper, from opposite sides (the mean
  of the fingers' contact normals is shorter than 0.5: fingers side by side that push O do
  not hold it).
* ``on(O, S)``: O is supported by S and not in a gripper (it rests on S).
* ``broken(O)``: O's object model reports it broken. An interval of a state fluent of O
  (``broken``, ``upside_down``) that spans the end of a ``drop(O)`` is reported as two:
  up to the drop's end, and from the next sample (a state O lands in holds after the drop).
* ``upside_down(P)``: the plane fitted to the logged segment frames of deformable body P
  (``P`` and its links ``P/...``; a pancake) has its upper side's normal pointing down (see
  :mod:`projection_server.timeline.turning`).

Events (``[name, args, start, end]``, points have start = end):

* ``grasp(O)``: an ``in_gripper(O)`` interval begins.
* ``release(O)``: it ends while its gripper's command is ``open``.
* ``lift(O)``: a ``supported_by(O, S)`` interval ends while O is in the gripper.
* ``slip(O)``: O is lost from the grasp: it leaves the gripper while the command is not
  ``open`` (a point at the grasp's end), or it is held to the end of the grasp sunk more
  than ``slip_distance`` below where the gripper carried it (it slides out between the
  fingers and ends below the lift's height; the event spans from the last sample sunk less
  than a fifth of that to the sample that exceeds it). Motion is measured relative to the
  gripper's fingers from ``grasp_settle`` after the grasp, while O is not broken.
* ``shift(O)``: O moves within the grasp and is not lost: while held and not broken it
  moves by more than ``slip_distance`` or turns by more than ``slip_angle`` relative to the
  fingers (from the last sample within a fifth of the threshold to the sample that crosses
  it), and no ``slip(O)`` ends that grasp.
* ``break(O)``: ``broken(O)`` begins.
* ``flip(P)``: ``upside_down(P)`` begins.
* ``drop(O)``: a free fall: O touches nothing (no contact of at least
  ``contact_force_min``) while it falls at least ``drop_min_fall`` below where it last
  touched something (1 cm, 45 ms from rest: two or three samples at 60 Hz). The event spans
  the samples without contact. Where it last touched is the higher of its heights at the
  ends of the period of the last sample with contact (that contact was within it); the
  fall's lowest point counts the sample it lands in. A body resting, sliding or carried
  touches something in every sample, and does not drop.
* ``tipped_over(O)``: O's z axis is more than ``tip_angle`` from its z axis at the first
  sample, for a body O; a point at the first sample where it is, once per projection (what
  is asked is whether O tipped over; ``upside_down`` and ``final_pose`` say how it ended).
  A tool a program turns (the poured cup, the flipped spatula) tips over too.
* ``collision(R, O)``: robot R touches O with any link but its base (which may rest on its
  mount), while O is not in R's gripper (``in_gripper`` of R's fingers, gaps merged) and
  not the target of R's task (``TaskState.target`` of the sample), and O is not R: an
  event over each maximal interval of such samples (gaps merged). Without task states of
  R, a contact during which O is in R's gripper at some time is the approach (or release)
  of a grasp, not a collision.

* ``spill(F)``: a particle of fluid F first reaches the table (its centre within two
  particle radii of the table's top, or lower).

Of a batter F whose heat is simulated (a particle fluid on a heated pancake maker, or one
that brings temperatures or bonds: :mod:`projection_server.simulation.batter.heat`; see
:mod:`projection_server.timeline.cooking`):

* fluent ``set(F)``: at least ``SET_FRACTION`` (0.5) of F's particles are set (have reached
  its ``setting_temperature``); event ``set(F)``: it begins.
* fluent ``upside_down(F)``: the pancake that emerged from F, its largest cluster of bonded
  particles (at least ``MIN_CLUSTER``, a tenth, of F's particles), lies upside down: the
  rotation (Kabsch) that carries its particles from where each of them was first seen set
  to where they are turns the up axis at least 60 deg below level; event ``flip(F)``: it
  begins. So the paper's ``holds(upside_down(_), _, TL)`` asks of the pancake that
  emerged as of the jointed one.

Quantities: ``max_load(O)`` [N] and ``load_limit(O)`` [N] of modelled objects; of every body
O, ``lift_height(O)`` [m] (highest minus initial height), ``displacement(O)`` [m] (the
distance from its first to its last sample's position), ``max_speed(O)`` [m/s] (the
largest distance between two successive samples' positions over their time apart) and
``final_pose(O)``, its world pose
``[[X, Y, Z], [QX, QY, QZ, QW]]`` [m] at the last sample (a unit quaternion). Of particle
fluids (at the last sample, see :mod:`projection_server.timeline.pouring`):
``particles_on(M)`` per pancake maker M, ``particles_in(C)`` per cup C,
``particles_spilled(F)`` (neither in a cup nor on a maker) per fluid F,
``particles_on_positions(M)``, the world positions ``[X, Y, Z]`` [m] of the particles on M
(what ``object_model(pancake, _{particles: Points}, E)`` builds a pancake from), and of the
particles on M ``centroid_offset_x(M)``, ``centroid_offset_y(M)`` [m] (world axes, relative to M's
centre; left out without particles), ``roundness(M)`` and ``spread_area(M)`` [m^2] (the
area of a uniform disc of the particles' second moments; both left out below two particles).
The fluent ``on(F, M)`` comes from the contacts, like every ``on``. Of a batter F (at the
last sample): ``temperature(F)`` [deg C], the mean of its particles'; ``set_fraction(F)``,
the fraction of them that is set; and its state, what a next projection starts from (the
fluid's ``positions``, ``temperatures`` and ``bonds``): ``particle_positions(F)`` (world
``[X, Y, Z]`` [m] of each particle), ``particle_temperatures(F)`` [deg C] and ``bonds(F)``,
the bonds in force as ``[I, J]`` particle index pairs. Of the batter on a pancake maker M
(particles of fluids whose heat is logged), in the order of ``particles_on_positions(M)``:
``particles_on_temperatures(M)`` [deg C] and ``particles_on_bonds(M)`` (the bonds between
them, as index pairs into that list): what lies on the pan, handed on without what stayed
in the cup.
"""

from __future__ import annotations

import dataclasses
import json
import os
from typing import Any, TYPE_CHECKING

import numpy as np

from projection_server.settings import TimelineSettings
from projection_server.timeline.fluids import Fluids
from projection_server.timeline.rules import Rules, sorted_events
from projection_server.timeline.samples import Samples
from projection_server.timeline.vocabulary import check, vocabulary

if TYPE_CHECKING:
    from collections.abc import Iterable

    from projection_server.bags.schema import Record

__all__ = ['translate_records']


def translate_records(records: Iterable[Record], bag: str | os.PathLike[str],
                      scenario: Any) -> dict[str, Any]:
    """The timeline of a projection from what its monitor logged, as plain
    :class:`~projection_server.bags.Record` s (a worker's own projection: the same
    timeline as its bag's); ``bag`` is the bag's path, ``scenario`` the projection's
    checked scenario (its ``entities``, each with ``name``, ``cls``, ``pose`` and
    ``properties``). Its ``vocabulary`` is what any timeline of the scenario can name
    (:func:`~projection_server.timeline.vocabulary.vocabulary`); every term of the timeline
    is checked to be in it.

    Raises:
        ProjectionError: kind ``bag_error`` if the records are not a projection's, or if
            the timeline has a term its vocabulary does not declare.
    """
    samples = Samples()
    for record in records:
        samples.add(*record)
    info, samples_ = samples.finish(bag)
    settings_json = json.loads(info.settings_json)
    settings = TimelineSettings.recorded(settings_json['timeline'])
    rules = Rules(samples_, settings)
    fluids = Fluids(samples_, scenario)
    timeline = {
        'fluents': sorted(rules.fluents() + fluids.fluents(),
                          key=lambda r: (r[2], r[0], r[1])),
        'events': sorted_events(rules.events() + fluids.events()),
        'quantities': [[name, args, _plain(value)] for name, args, value
                       in rules.quantities() + fluids.quantities()],
        'vocabulary': vocabulary(scenario),
        'meta': {
            'bag': os.fspath(bag), 'scenario': info.scenario_name, 'program': info.program,
            'params': json.loads(info.parameters_json), 'job_key': info.job_key,
            'code_version': info.code_version,
            'duration': samples_[-1].t if samples_ else 0.0, 'samples': len(samples_),
            'timeline_settings': dataclasses.asdict(settings),
        },
    }
    check(timeline, timeline['vocabulary'])
    return timeline


def _plain(value: Any) -> Any:
    """Numbers as Python's own (in memory they may still be numpy scalars)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value
