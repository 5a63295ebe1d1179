"""Physics settings per program and per query: ranges, precedence, and the cache key."""

from __future__ import annotations

import hashlib

import pytest

from projection_server.simulation import Job, load_settings, ProjectionError, Settings
from projection_server.canonical import canonical_json
from projection_server.simulation.job import code_version
from projection_server.settings import PHYSICS_OPTIONS


@pytest.fixture(scope='module')
def settings():
    data = load_settings().to_dict()
    data['programs'] = {'pour': {'solver_iterations': 20, 'rate_hz': 120}}
    return Settings.from_dict(data)


def test_a_finer_step_keeps_the_control_and_logging_rates(settings):
    base, finer = settings, settings.for_projection('grasp_object', {'rate_hz': 960})
    assert finer.physics.rate_hz == 960 and finer.physics.time_step == pytest.approx(1 / 960)
    for name in ('steps_per_control', 'steps_per_log'):
        assert (getattr(finer.control, name) / 960
                == pytest.approx(getattr(base.control, name) / base.physics.rate_hz))


def test_the_query_overrides_the_program_which_overrides_the_file(settings):
    pour = settings.for_projection('pour')
    assert (pour.physics.solver_iterations, pour.physics.rate_hz) == (20, 120)
    assert pour.control.steps_per_control * 60 == 120
    grasp = settings.for_projection('grasp_object')
    assert grasp.physics == settings.physics and grasp.programs == {}
    chosen = settings.for_projection('pour', {'solver_iterations': 300})
    assert (chosen.physics.solver_iterations, chosen.physics.rate_hz) == (300, 120)


def test_the_settings_of_a_projection_are_a_fixed_point(settings):
    once = settings.for_projection('pour', {'rate_hz': 480})
    assert once.for_projection('pour', {'rate_hz': 480}) == once
    assert Settings.from_dict(once.to_dict()) == once


def test_an_engines_settings_lie_under_the_programs_and_the_querys(settings):
    from dataclasses import replace

    mujoco = settings.for_projection('grasp_object', {'engine': 'mujoco'})
    assert mujoco.physics.rate_hz == settings.engines['mujoco']['rate_hz'] == 120
    assert mujoco.control.steps_per_log * 60 == 120   # logging keeps its 60 Hz
    assert mujoco.for_projection('grasp_object') == mujoco   # a fixed point
    assert settings.for_projection('grasp_object').physics.rate_hz == 240   # PyBullet's
    assert settings.for_projection('grasp_object', {'engine': 'mujoco', 'rate_hz': 480}
                                   ).physics.rate_hz == 480
    # The fixture's pour runs at 120 Hz with 20 iterations, on either engine.
    pour = settings.for_projection('pour', {'engine': 'mujoco'}).physics
    assert (pour.rate_hz, pour.solver_iterations) == (120, 20)
    # A node whose default engine is MuJoCo runs a query that names none with its settings.
    node = replace(settings, physics=replace(settings.physics, engine='mujoco'))
    assert node.for_projection('grasp_object') == mujoco
    described = {d['name']: d for d in settings.describe_physics('grasp_object', 'mujoco')}
    assert described['rate_hz']['default'] == 120
    assert {d['name']: d for d in settings.describe_physics('grasp_object')
            }['rate_hz']['default'] == 240


@pytest.mark.parametrize('engines, words', [
    ({'ode': {'rate_hz': 120}}, ['engines.ode', 'pybullet', 'mujoco']),
    ({'mujoco': {'rate_hz': 100}}, ['engines.mujoco', 'multiple of 60']),
    ({'mujoco': {'engine': 'pybullet'}}, ['engines.mujoco', 'no engine']),
])
def test_an_engines_settings_in_the_file_are_checked_too(engines, words):
    data = load_settings().to_dict()
    data['engines'] = engines
    with pytest.raises(ProjectionError) as info:
        Settings.from_dict(data)
    assert all(word in str(info.value) for word in words), str(info.value)


@pytest.mark.parametrize('physics, words', [
    ({'rate_hz': 1000}, ['rate_hz', 'multiple of 60']),
    ({'rate_hz': 30}, ['rate_hz', '[60, 4800]']),
    ({'solver_iterations': 0}, ['solver_iterations', '[1, 2000]']),
    ({'solver_iterations': 2.5}, ['solver_iterations', 'integer']),
    ({'contact_erp': 'high'}, ['contact_erp', 'number']),
    ({'gravity': 3.0}, ['gravity', 'accepted', 'rate_hz']),
])
def test_a_setting_out_of_its_range_is_refused_naming_it(settings, make_scenario, physics,
                                                         words):
    with pytest.raises(ProjectionError) as info:
        Job.checked(make_scenario(), 'grasp_object', {}, physics).key(settings)
    assert info.value.kind == 'invalid_settings'
    assert all(word in str(info.value) for word in words), str(info.value)


def test_a_programs_settings_in_the_file_are_checked_too():
    data = load_settings().to_dict()
    data['programs'] = {'pour': {'solver_iterations': -1}}
    with pytest.raises(ProjectionError, match='programs.pour: solver_iterations'):
        Settings.from_dict(data)


def test_the_cache_key_is_that_of_the_settings_the_projection_runs_with(settings,
                                                                        make_scenario):
    plain = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0})
    finer = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0}, {'rate_hz': 960})
    explicit = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0},
                           {'rate_hz': settings.physics.rate_hz})
    assert finer.key(settings) != plain.key(settings) == explicit.key(settings)


@pytest.mark.parametrize('physics', [None, {'rate_hz': 960, 'solver_iterations': 40}])
def test_the_cache_key_hashes_the_canonical_json_of_job_settings_and_code(
        settings, make_scenario, physics):
    # The key is made of parts kept per job and per settings: it is still the hash of the
    # canonical JSON of the whole, and a job made without checked() has the same key.
    job = Job.checked(make_scenario(), 'pour' if physics else 'grasp_object',
                      {'force': 5.0} if physics is None else {'angle': 2.0}, physics)
    # The scenario counts by its content: its name is left out.
    content = {k: v for k, v in job.scenario.items() if k != 'name'}
    whole = canonical_json({'scenario': content, 'program': job.program,
                            'params': job.params, 'settings': job.settings(settings).to_dict(),
                            'code': code_version()})
    assert job.key(settings) == hashlib.sha256(whole.encode()).hexdigest()
    assert Job(job.scenario, job.program, job.params, job.physics).key(settings) == job.key(
        settings)
    assert job.key(settings) == job.key(settings)   # from the kept parts


def test_every_option_is_a_field_of_the_physics_with_a_default_in_its_range(settings):
    described = {d['name']: d for d in settings.describe_physics('pour')}
    assert set(described) == set(PHYSICS_OPTIONS)
    for name, d in described.items():
        if 'values' in d:   # a choice of names: the engine
            assert d['default'] in d['values'], name
            continue
        assert d['min'] <= d['default'] <= d['max'], name
    assert described['solver_iterations']['default'] == 20
    assert described['rate_hz']['multiple_of'] == 60


def test_the_engine_is_a_setting_that_names_one_of_the_engines(settings):
    from projection_server.settings import ENGINES
    from projection_server.errors import ProjectionError

    assert settings.physics.engine == 'pybullet'
    mujoco = settings.for_projection('grasp_object', {'engine': 'mujoco'})
    assert mujoco.physics.engine == 'mujoco'
    assert mujoco.to_dict()['physics']['engine'] == 'mujoco'
    # PyBullet's settings, chosen or not, are what they were before there was a choice.
    assert 'engine' not in settings.for_projection('grasp_object', {'engine': 'pybullet'}
                                                   ).to_dict()['physics']
    assert (settings.projection_json('grasp_object', {'engine': 'pybullet'})
            == settings.projection_json('grasp_object'))
    assert (settings.projection_json('grasp_object', {'engine': 'mujoco'})
            != settings.projection_json('grasp_object'))
    with pytest.raises(ProjectionError) as info:
        settings.for_projection('grasp_object', {'engine': 'ode'})
    assert all(name in str(info.value) for name in ENGINES)
