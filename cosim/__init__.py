"""auv-cosim: the REMUS 100 with internal actuators as FMI 2.0 co-simulation FMUs.

The Python API (:mod:`cosim.api`, docs/api.md)::

    import cosim

    run = cosim.run("bs-3", stop_time=20.0, start={"plant.v_0": -0.05})
    run.results  # pandas DataFrame indexed by time, columns "<instance>.<variable>", SI
    run.summary  # the summary.json dictionary
    study = cosim.sweep("study.toml", workers=2)
    study.table  # one row per run
"""

from cosim.api import Run, RunError, Study, build_fmus, load_scenario, run, sweep

__all__ = ["Run", "RunError", "Study", "build_fmus", "load_scenario", "run", "sweep"]
