"""A projection job and its content key (what makes two projections the same)."""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import hashlib
import json
from pathlib import Path
import threading
from typing import Any, TYPE_CHECKING

from projection_server import assets
from projection_server.canonical import canonical_json
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.simulation.programs import get as get_program
from projection_server.simulation.programs.plan import check_plan
from projection_server.simulation.scenario import model_files, parse_scenario
from projection_server.settings import check_physics

if TYPE_CHECKING:
    from projection_server.settings import Settings

__all__ = ['Job', 'code_version']


@functools.cache
def code_version() -> str:
    """Package version plus a digest of the code, assets and messages that shape a bag."""
    from importlib import metadata

    from projection_server.bags import message_definitions

    try:
        version = metadata.version('projection_server')
    except metadata.PackageNotFoundError:
        version = '0+source'
    package = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    files = sorted([*(package / 'simulation').rglob('*'), *(package / 'bags').rglob('*'),
                    package / 'settings.py', package / 'canonical.py'])
    for path in files:
        if path.is_file() and path.suffix in {'.py', '.urdf', '.yaml'}:
            digest.update(path.relative_to(package).as_posix().encode())
            digest.update(path.read_bytes())
    for name, text in sorted(message_definitions().items()):
        digest.update(name.encode())
        digest.update(text.encode())
    return f'{version}+{digest.hexdigest()[:16]}'


# The canonical JSON of the scenarios parse_scenario accepted last (oldest first), the
# model files each names and its content's canonical JSON (:func:`_content`).
_VALID_SCENARIOS: dict[str, tuple[tuple[str, ...], str]] = {}
_VALID_LOCK = threading.Lock()


@dataclass(frozen=True, eq=False)
class Job:
    """One projection: a scenario description, a program name, its parameter values and the
    physics settings the query chose (:data:`~projection_server.settings.
    PHYSICS_OPTIONS`; the others come from the settings file); for the program ``plan``, the
    plan itself (its steps, with parameter references:
    :mod:`projection_server.simulation.programs.plan`).

    Construct with :meth:`checked`, which validates everything that can be checked without a
    simulator and fills in parameter defaults. ``files`` are the content digests of the
    model files the scenario names (:func:`projection_server.assets.digest`), by path:
    a projection of an edited mesh is another projection.
    """

    scenario: dict[str, Any]
    program: str
    params: dict[str, float]
    physics: dict[str, float] = field(default_factory=dict)
    plan: list[Any] | None = None
    files: dict[str, str] = field(default_factory=dict)

    @classmethod
    def checked(cls, scenario: Any, program: str, params: Any, physics: Any = None,
                plan: Any = None) -> Job:
        """Validate and normalize (raises ProjectionError with the matching kind).

        A model file must be an absolute path of a well formed file inside the asset
        directories (:func:`projection_server.assets.checked`), whichever client made the
        scenario; it is checked each time (a file may change), its content at most once
        per modification."""
        # A JSON round trip drops janus/tuple types and fails early on non-JSON data.
        text = canonical_json(scenario)
        with _VALID_LOCK:   # queries check their jobs from threads of their own
            known = _VALID_SCENARIOS.get(text)
            if known is None:   # a query's projections share their scenario
                known = (tuple(model_files(parse_scenario(scenario))),
                         _content(json.loads(text)))
                if len(_VALID_SCENARIOS) >= 64:
                    del _VALID_SCENARIOS[next(iter(_VALID_SCENARIOS))]
                _VALID_SCENARIOS[text] = known
        paths, content = known
        files = {path: assets.checked(path) for path in paths}
        unit = get_program(program)
        values = unit.check(params if params is not None else {})
        chosen = check_physics(physics if physics is not None else {})
        if unit.takes_plan:
            plan = json.loads(canonical_json(plan))
            check_plan(plan, values)
        elif plan is not None:
            raise ProjectionError(ErrorKind.INVALID_PARAMETERS,
                                  f'{program} is a named program: it takes no plan')
        job = cls(json.loads(text), program, values, chosen, plan=plan, files=files)
        object.__setattr__(job, '_scenario_json', text)
        object.__setattr__(job, '_content_json', content)   # what the keys are made of
        return job

    @functools.cached_property
    def _scenario_json(self) -> str:
        return canonical_json(self.scenario)

    @functools.cached_property
    def _content_json(self) -> str:
        return _content(self.scenario)

    def settings(self, settings: Settings) -> Settings:
        """The settings this projection runs with, given those of the settings file."""
        return settings.for_projection(self.program, self.physics)

    def check_engine(self, settings: Settings) -> None:
        """The engine of this projection at ``settings`` can run it
        (:func:`~projection_server.simulation.engines.check`; raises ProjectionError)."""
        _check_engine(self.settings(settings).physics.engine, self.program,
                      self._scenario_json)

    def family(self, settings: Settings) -> str | None:
        """Equal for projections that may share their first steps
        (:mod:`~projection_server.simulation.branching`): same scenario, program, settings
        and set-up parameters. None if the program does not say which parameters set up, or
        shares no steps on this engine (``Program.forks``)."""
        program = get_program(self.program)
        if not program.shares_steps(self.settings(settings).physics.engine):
            return None
        setup = program.setup(self.params)
        parts = {'scenario': self._content_json, 'program': canonical_json(self.program),
                 'setup': canonical_json(setup),
                 'settings': settings.projection_json(self.program, self.physics),
                 **self._files_part()}
        if self.plan is not None:
            parts['plan'] = canonical_json(self.plan)
        return hashlib.sha256(_assembled(parts).encode()).hexdigest()

    def key(self, settings: Settings) -> str:
        """Content hash of job, its settings, the code version and the content of its model
        files: the cache key and the bag's name. Physics chosen by the query count as what
        they amount to, so choosing the program's own settings finds the same bag. The
        scenario counts by its content, not its name: a created scenario (``scenario_N``)
        with the entities of another, or of a knowledge base scenario, is the same
        projection, and finds the bag the first one made (whose ``/projection/info``
        names that first scenario)."""
        parts = {'scenario': self._content_json, 'program': canonical_json(self.program),
                 'params': canonical_json(self.params),
                 'settings': settings.projection_json(self.program, self.physics),
                 'code': canonical_json(code_version()), **self._files_part()}
        if self.plan is not None:
            parts['plan'] = canonical_json(self.plan)
        return hashlib.sha256(_assembled(parts).encode()).hexdigest()

    def _files_part(self) -> dict[str, str]:
        # Absent for a scenario without model files: its key is what it always was.
        return {'files': canonical_json(self.files)} if self.files else {}


@functools.lru_cache(maxsize=256)
def _check_engine(engine: str, program: str, scenario_json: str) -> None:
    from projection_server.simulation import engines

    engines.check(engine, program, parse_scenario(json.loads(scenario_json)))


def _content(scenario: dict[str, Any]) -> str:
    """The canonical JSON of a scenario description without its name: what the simulation
    is built from (the entities, a robot world's snapshot)."""
    return canonical_json({k: v for k, v in scenario.items() if k != 'name'})


def _assembled(parts: dict[str, str]) -> str:
    """:func:`canonical_json` of a dict from the canonical JSON of its values: the same text
    (the scenario's and the settings' are made once, not for every key)."""
    return '{' + ','.join(f'{json.dumps(name)}:{text}'
                          for name, text in sorted(parts.items())) + '}'
