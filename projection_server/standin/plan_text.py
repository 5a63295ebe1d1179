"""The plan a client sends, as text: the plan language of ``plan/1`` or its JSON form.

The stand-in robot takes the same plans a projection does. The plan language's text is
parsed and checked by Prolog, by the plan language's own checker (``plan_template/3`` of
``prolog/plan.pl``), into the JSON form the plan program takes; that form is also accepted
as it is. Then :func:`~projection_server.simulation.programs.plan.check_plan` checks the
values and bounds, as for any projection::

    >>> parse_plan('[close_gripper(5), wait(0.2)]').steps
    [{'action': 'close_gripper', 'force': 5.0}, {'action': 'wait', 'seconds': 0.2}]

This is the one module of the stand-in that calls SWI-Prolog (through janus); it loads
``plan.pl`` alone (the stand-in answers no queries). The text is bound through janus'
``inputs``, never formatted into goal text, and only read as a term: nothing in it runs.
"""

from __future__ import annotations

from dataclasses import dataclass
import json
import os
import threading
from typing import Any

from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.programs.plan import check_plan

__all__ = ['MAX_PLAN_CHARS', 'ParsedPlan', 'PlanTextError', 'parse_plan']

MAX_PLAN_CHARS = 100_000

_loaded = False
_load_lock = threading.Lock()

# Every variable of the goal that is no output starts with an underscore: janus returns
# the others, and a Prolog term it cannot convert is an error.
_PARSE = (
    "catch((term_string(_Plan, Text, [variable_names(_Names)]), "
    "findall(_N, member(_N=_, _Names), Variables), "
    "( Variables == [] -> plan:plan_template(_Plan, [], Template), "
    "findall(_S, (member(_Step, _Plan), term_string(_Step, _S)), Texts) "
    "; Template = [], Texts = [] ), Error = ''), _E, "
    "(Template = [], Texts = [], Variables = [], "
    "'$messages':translate_message(_E, _Lines, []), "
    "with_output_to(string(Error), print_message_lines(current_output, '', _Lines))))")


class PlanTextError(ProjectionError):
    """A plan that cannot be read or is not a plan (kind ``invalid_parameters``)."""

    def __init__(self, message: str):
        super().__init__(ErrorKind.INVALID_PARAMETERS, message)


@dataclass(frozen=True)
class ParsedPlan:
    """A checked plan: its steps in the plan program's form (``check_plan``'s, grounded)
    and each step as written (for feedback)."""

    template: list[dict[str, Any]]
    steps: list[dict[str, Any]]
    texts: list[str]


def parse_plan(text: str) -> ParsedPlan:
    """The plan ``text`` (the plan language, or the JSON list of steps), checked.

    Raises:
        PlanTextError: the text is neither, or names variables; ``check_plan``'s
            ProjectionError: a value out of range, a plan too long.
    """
    if not isinstance(text, str) or not text.strip():
        raise PlanTextError('the plan is empty: send a list of steps, e.g. "[wait(1)]"')
    if len(text) > MAX_PLAN_CHARS:
        raise PlanTextError(f'the plan has {len(text)} characters, more than '
                            f'{MAX_PLAN_CHARS}')
    template = _json_plan(text)
    if template is not None:
        texts = [json.dumps(step, sort_keys=True) for step in template]
    else:
        template, texts = _prolog_plan(text)
    return ParsedPlan(template, check_plan(template, {}), texts)


def _json_plan(text: str) -> list[Any] | None:
    """The JSON form's steps, or None if ``text`` is not a JSON list of objects."""
    try:
        value = json.loads(text)
    except ValueError:
        return None
    if isinstance(value, list) and value and all(isinstance(s, dict) for s in value):
        return value
    return None


def _prolog_plan(text: str) -> tuple[list[Any], list[str]]:
    janus = _janus()
    try:
        answer = janus.query_once(_PARSE, {'Text': text})
    except janus.PrologError as exc:
        raise PlanTextError(f'the plan cannot be read: {exc}') from exc
    if answer['Error']:
        message = ' '.join(str(answer['Error']).split())
        raise PlanTextError(f'the plan cannot be read: {message}')
    if answer['Variables']:
        names = ', '.join(map(str, answer['Variables']))
        raise PlanTextError(f'the plan names variables ({names}): a plan sent to a robot '
                            'has a number for each of them')
    return _plain(answer['Template']), [str(t) for t in answer['Texts']]


def _plain(value: Any) -> Any:
    """janus' values (its dicts, tuples) as JSON's."""
    return json.loads(json.dumps(value, default=_unknown))


def _unknown(value: Any) -> Any:
    if isinstance(value, (tuple, set)):
        return list(value)
    if hasattr(value, 'keys'):
        return {str(k): value[k] for k in value.keys()}
    return str(value)


def _janus() -> Any:
    global _loaded
    try:
        import janus_swi as janus
    except ImportError as exc:
        raise PlanTextError(f'the plan language needs janus_swi: {exc}') from exc
    with _load_lock:
        if not _loaded:
            path = os.path.join(_prolog_dir(), 'plan.pl')
            try:
                janus.query_once('use_module(File)', {'File': path})
            except janus.PrologError as exc:
                raise PlanTextError(f'cannot load {path}: {exc}') from exc
            _loaded = True
    return janus


def _prolog_dir() -> str:
    from ament_index_python.packages import get_package_share_directory
    return os.path.join(get_package_share_directory('projection_server'), 'prolog')
