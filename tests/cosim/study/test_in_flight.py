"""A study's runs in flight on a worker are stopped together as the study ends there
(:mod:`cosim.study.in_flight`): a run the study's end did not stop went on until Dask's
nanny killed its worker, which left the worker's scratch folder behind."""

from __future__ import annotations

from cosim.study.in_flight import STOPPED_BY, RunsInFlight


def test_the_study_s_end_stops_its_runs_in_flight_and_those_started_later() -> None:
    runs = RunsInFlight()
    with runs.run() as first, runs.run() as second:
        assert not first.requested and not second.requested
        assert runs.stop_all() == 2
        assert first.requested and second.requested
        assert first.reason == f"stopped by {STOPPED_BY}"
    with runs.run() as late:  # its task taken as the study's plugin was torn down
        assert late.requested
    assert runs.stop_all() == 0  # none left in flight
