"""What a timeline of a scenario can name: its fluents, events and quantities (each a name
and the kinds of its arguments) and its objects (the scenario's entities, parts included).

The rules of :mod:`~projection_server.timeline.rules` and
:mod:`~projection_server.timeline.fluids` emit the terms declared here; the particle
fluids' terms only when the scenario has a particle fluid. :func:`translate_records`
checks every term it emits against this vocabulary (:func:`check`), so a rule that emits a
name left out here fails every projection at once instead of drifting. Prolog checks a
query's conditions against the same vocabulary before it projects (``timeline.pl``; a
scenario description's is :func:`projection_server.projection.vocabulary`)::

    >>> vocabulary(parse_scenario(description))['events']
    [['break', ['object']], ['collision', ['object', 'object']], ...]

An argument's kind is ``object`` (an entity of the scenario) or ``property`` (a property
name, as in ``sampled(Entity, Property)``).
"""

from __future__ import annotations

from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError

if TYPE_CHECKING:
    from collections.abc import Mapping

__all__ = ['BODY', 'FLUID', 'check', 'vocabulary']

O, P = 'object', 'property'

# Of every scenario: the rules' terms (rules.py), and the draws of a world from a belief
# (projection.timeline adds them as sampled(Entity, Property)).
BODY: Mapping[str, Mapping[str, tuple[str, ...]]] = {
    'fluents': {'contact': (O, O), 'supported_by': (O, O), 'in_gripper': (O,),
                'on': (O, O), 'broken': (O,), 'upside_down': (O,)},
    'events': {'grasp': (O,), 'release': (O,), 'lift': (O,), 'slip': (O,), 'shift': (O,),
               'break': (O,), 'flip': (O,), 'drop': (O,), 'tipped_over': (O,),
               'collision': (O, O)},
    'quantities': {'max_load': (O,), 'load_limit': (O,), 'lift_height': (O,),
                   'displacement': (O,), 'max_speed': (O,), 'final_pose': (O,),
                   'sampled': (O, P)},
}

# Of a scenario with a particle fluid (fluids.py): pouring, and a batter's heat.
FLUID: Mapping[str, Mapping[str, tuple[str, ...]]] = {
    'fluents': {'set': (O,), 'upside_down': (O,)},
    'events': {'spill': (O,), 'set': (O,), 'flip': (O,)},
    'quantities': {name: (O,) for name in (
        'particles_on', 'particles_in', 'particles_spilled', 'particles_on_positions',
        'centroid_offset_x', 'centroid_offset_y', 'roundness', 'spread_area',
        'particles_on_temperatures', 'particles_on_bonds', 'temperature', 'set_fraction',
        'particle_temperatures', 'particle_positions', 'bonds')},
}

_KINDS = ('fluents', 'events', 'quantities')
_SINGULAR = {'fluents': 'fluent', 'events': 'event', 'quantities': 'quantity'}


def vocabulary(scenario: Any) -> dict[str, Any]:
    """The vocabulary of the timelines of the checked ``scenario`` (its ``entities``, each
    with a ``name`` and a ``unit`` whose ``fluid_role`` says what it is to a fluid):
    ``{'fluents': [[name, kinds], ...], 'events': ..., 'quantities': ..., 'objects': [name,
    ...]}``, sorted."""
    fluid = any(entity.unit.fluid_role is not None
                and entity.unit.fluid_role(entity)[0] == 'fluid'
                for entity in scenario.entities)
    out: dict[str, Any] = {}
    for kind in _KINDS:
        terms = dict(BODY[kind])
        if fluid:
            terms.update(FLUID[kind])
        out[kind] = [[name, list(args)] for name, args in sorted(terms.items())]
    out['objects'] = sorted(entity.name for entity in scenario.entities)
    return out


def check(timeline: Mapping[str, Any], vocab: Mapping[str, Any]) -> None:
    """Every fluent, event and quantity of ``timeline`` (``[name, args, ...]`` records) is
    one of ``vocab``'s, with its arity, and its object arguments are its objects.

    Raises:
        ProjectionError: kind ``bag_error``, naming the first record that is not.
    """
    objects = set(vocab['objects'])
    for kind in _KINDS:
        known = {name: args for name, args in vocab[kind]}
        for record in timeline.get(kind, ()):
            name, args = record[0], record[1]
            kinds = known.get(name)
            if kinds is None or len(kinds) != len(args) or any(
                    k == O and a not in objects for k, a in zip(kinds, args)):
                raise ProjectionError(
                    ErrorKind.BAG_ERROR,
                    f'the timeline has the {_SINGULAR[kind]} {name}{tuple(args)!r}, which '
                    'its vocabulary (projection_server.timeline.vocabulary) does not '
                    'declare')
