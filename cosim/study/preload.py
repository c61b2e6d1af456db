"""Imported by each local study worker as it starts (Dask's worker ``preload``), while
the client still imports and checks the study: the modules a run needs. What is specific
to the study's FMUs -- their libraries, their modules, their compiled code -- is loaded
later, by the study plugin's set-up (:func:`cosim.study.task.warm_up`).

Not imported here: the FMUs' own packages (``plant_fmu``, ``controller_fmu``; an FMU
imports the copy it ships, and one already imported would shadow it) and numba (the
plant's code sets numba's cache folder before numba is first imported).
"""

import fmpy.fmi2  # noqa: F401  (loaded once, now)

import cosim.study.task  # noqa: F401  (the run's modules: runner, engine, outputs)


def dask_setup(worker: object) -> None:
    """A local worker ignores SIGINT: a Ctrl-C is the client's to handle, which ends the
    study and its cluster (:mod:`cosim.study.signals`); the workers of a cluster started
    on a thread (early, while the study is checked) do not inherit the client's ignoring."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
