"""The entry point for Prolog: simulate(), timeline() and translate_bag() of
docs/contracts.md."""

from __future__ import annotations

import pytest

from projection_server import projection
from projection_server.simulation import ProjectionError
from projection_server.workers.run import translate_bag


@pytest.fixture
def bag_dir(tmp_path, monkeypatch):
    """The process-wide pool, writing into a fresh directory; stopped afterwards."""
    projection.shutdown()
    monkeypatch.setenv('PROJECTION_SERVER_BAG_DIR', str(tmp_path))
    yield tmp_path
    projection.shutdown()


def test_simulate_returns_a_bag_that_translates_to_a_timeline(bag_dir, make_scenario):
    path = projection.simulate(make_scenario(), 'grasp_object',
                               {'force': 5, 'position': 0.0}, 60.0)
    assert path.startswith(str(bag_dir))
    timeline = translate_bag(path)
    assert ['grasp', ['egg1']] in [e[:2] for e in timeline['events']]
    assert timeline['meta']['params'] == {'force': 5.0, 'position': 0.0, 'lift_time': 1.0}


def test_the_timeline_comes_from_the_worker_once_and_then_from_the_bag(
        bag_dir, make_scenario, monkeypatch):
    from projection_server.workers import run

    path = projection.simulate(make_scenario(), 'grasp_object',
                               {'force': 11, 'position': 0.0}, 60.0)
    reads = []
    monkeypatch.setattr(run, 'read_records',
                        lambda *a: reads.append(a) or _read_records(*a))
    made = projection.timeline(path)
    assert reads == []
    again = projection.timeline(path)
    assert len(reads) == 1
    assert made == again


def _read_records(*args):
    from projection_server.bags import read_records

    return read_records(*args)


def test_simulate_rejects_bad_input_before_starting_a_worker(bag_dir, make_scenario):
    with pytest.raises(ProjectionError) as info:
        projection.simulate(make_scenario(), 'grasp_object', {'force': -1.0}, 10.0)
    assert info.value.kind == 'invalid_parameters'
    assert list(bag_dir.iterdir()) == []


def test_translating_something_else_than_a_bag_fails_clearly(tmp_path):
    with pytest.raises(ProjectionError) as info:
        translate_bag(tmp_path / 'missing')
    assert info.value.kind == 'bag_error'


@pytest.fixture(scope='module')
def simulator():
    from projection_server.simulation.runner import Simulator

    simulator = Simulator()
    yield simulator
    simulator.close()


@pytest.mark.parametrize('engine', ['pybullet', 'mujoco'])
def test_a_projection_stopped_by_an_error_keeps_every_sample_in_its_bag(
        simulator, make_scenario, tmp_path, engine):
    # The monitor holds its samples and writes them many at once: a step that raises (a
    # cancelled run on the stand-in robot) still leaves them all in the bag, which gives
    # the timeline of the records, up to the last sample.
    from projection_server.bags import BagWriter
    from projection_server.settings import load_settings
    from projection_server.simulation.job import Job
    from projection_server.simulation.runner import Projection
    from projection_server.timeline import translate_records

    class Stop(Exception):
        pass

    job = Job.checked(make_scenario(), 'grasp_object', {'force': 5.0, 'position': 0.0},
                      {'engine': engine})
    with BagWriter(tmp_path / 'stopped') as bag:
        projection = Projection(simulator, job, load_settings(), bag)
        physics = projection.physics
        stop_at = physics.settings.control.steps_per_log * 100 + 1   # after 100 samples

        def hook():
            if physics.step_count == stop_at:
                raise Stop

        physics.step_hooks.append(hook)
        with pytest.raises(Stop):
            projection.advance()
    timeline = translate_records(projection.monitor.records, tmp_path / 'stopped',
                                 projection.scenario)
    assert timeline['meta']['samples'] == 100
    assert translate_bag(tmp_path / 'stopped') == timeline
