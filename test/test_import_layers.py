"""The package's imports follow its pipeline.

A query goes service -> projection (Prolog's entry to the simulation side) -> workers ->
simulation -> bags -> timeline, and its answer comes back the same way. A module may import
its own stage and later ones, never an earlier one; every stage may import the vocabulary
they share (the error, canonical JSON, the settings, the bag schema, the model files). The
client imports no stage of the server at all. Imports under ``TYPE_CHECKING`` count too.
"""

from __future__ import annotations

import ast
from pathlib import Path

import projection_server

PACKAGE = Path(projection_server.__file__).parent
STAGES = ['service', 'projection', 'workers', 'simulation', 'bags', 'timeline']
SHARED = {'errors', 'canonical', 'settings', 'bags.schema', 'assets', 'geometry', 'lifetime'}
# Modules of a stage that are not named as the stage: the projection layer's beliefs (it
# draws the worlds of uncertain properties before a job is made) and selection (the
# statistics of a robust choice); the service's reading of the robot's world (its node
# subscribes, Prolog's robot_world/2 makes scenarios of it).
MEMBERS = {'beliefs': 'projection', 'selection': 'projection', 'world': 'service'}
# Re-exports at the old paths, kept for one release; tools that drive the whole service or
# read its bags (the renderer reads a bag and its timeline, as a worker makes it); the
# stand-in robot, which runs plans as a worker does and translates them as its timeline.
OUTSIDE = {'node', 'launcher', 'bindings', 'reproduce', 'render', 'standin'}


def _module(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts.pop()
    return '.'.join(parts)


def _part(module: str) -> str:
    """The stage, shared vocabulary, client or outside part that ``module`` (relative to
    the package) belongs to."""
    for shared in SHARED:
        if module == shared or module.startswith(shared + '.'):
            return 'shared'
    head = module.split('.')[0]
    head = MEMBERS.get(head, head)
    if head in STAGES or head in OUTSIDE or head == 'client':
        return head
    return ''


def _imports(path: Path) -> set[str]:
    """The package's modules that ``path`` imports (relative names)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f'{node.module}.{alias.name}' for alias in node.names]
        for name in names:
            if name.startswith('projection_server.'):
                relative = name[len('projection_server.'):]
                # `from pkg import module` names a module; `from module import name` not.
                if (PACKAGE / relative.replace('.', '/')).with_suffix('.py').is_file() or (
                        PACKAGE / relative.replace('.', '/') / '__init__.py').is_file():
                    found.add(relative)
    return found


def _edges() -> list[tuple[str, str, str, str]]:
    edges = []
    for path in sorted(PACKAGE.rglob('*.py')):
        module = _module(path)
        for imported in _imports(path):
            edges.append((module, _part(module), imported, _part(imported)))
    return edges


def test_every_module_belongs_to_a_stage_or_is_shared():
    unplaced = sorted({m for m, part, _, _ in _edges() if module_is_placed(m, part)})
    assert unplaced == []


def module_is_placed(module: str, part: str) -> bool:
    return module != '' and part == ''


def test_no_stage_imports_an_earlier_one():
    back = [f'{module} ({part}) imports {imported} ({other})'
            for module, part, imported, other in _edges()
            if part in STAGES and other in STAGES
            and STAGES.index(other) < STAGES.index(part)]
    assert back == []


def test_the_shared_vocabulary_imports_no_stage():
    wrong = [f'{module} imports {imported} ({other})'
             for module, part, imported, other in _edges()
             if part == 'shared' and other not in ('shared', '')]
    assert wrong == []


def test_the_client_imports_nothing_of_the_server():
    wrong = [f'{module} imports {imported} ({other})'
             for module, part, imported, other in _edges()
             if part == 'client' and other not in ('client', '')]
    assert wrong == []


def test_the_renderer_reads_bags_and_drives_no_service():
    wrong = [f'{module} imports {imported} ({other})'
             for module, part, imported, other in _edges()
             if part == 'render' and other in ('service', 'projection', 'client', 'reproduce')]
    assert wrong == []


def test_the_simulation_never_imports_the_timeline():
    assert not [edge for edge in _edges() if edge[1] == 'simulation' and edge[3] == 'timeline']
