"""auv-cosim: the REMUS 100 with internal actuators as FMI 2.0 co-simulation FMUs.

The Python API (:mod:`cosim.api`, docs/api.md), run where the FMUs are built (or
built into ``build/fmus`` at first use); ``auv-cosim scenarios`` lists the ids:

>>> import cosim
>>> run = cosim.run("bs-3", stop_time=1.0, start={"plant.v_0": -0.05})
>>> run  # run.results: a DataFrame indexed by time (s), columns "<instance>.<variable>"
Run(scenario='bs-3', complete=True, results=<101 rows x 35 columns>, out_dir=None)
>>> run.results.attrs["units"]["plant.yaw"], run.summary["complete"]  # summary.json
('rad', True)
>>> grid = {"plant.v_0": [-0.1, 0.1]}  # a study, in a script under if __name__ == "__main__"
>>> study = cosim.sweep({"scenario": "bs-3", "stop_time": 1.0, "grid": grid}, workers=1)
>>> study.table[["plant.v_0", "status"]]  # one row per run
   plant.v_0    status
0       -0.1  complete
1        0.1  complete

``cosim.__all__``: those functions, the types they return (``Run``, ``SavedRun``,
``Study``, ``Scenario``) and the errors they raise (``CosimError`` and its kinds
``ScenarioError``, ``StudyError``, ``RunError``; ``RunInterrupted`` and
``SweepInterrupted``, which are KeyboardInterrupts).

The API is imported at its first use (``cosim.run``, ``from cosim import sweep``), not with
the package: every command and module of the package (``cosim.cli``, a study's workers)
would otherwise import the runner and the outputs first (~0.25 s); ``auv-cosim sweep``
starts its workers' fork server before that (:mod:`cosim.study.fork_server`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from cosim.api import (
        Run,
        RunError,
        RunInterrupted,
        SavedRun,
        Study,
        SweepInterrupted,
        build_fmus,
        load_scenario,
        resume,
        run,
        sweep,
    )
    from cosim.errors import CosimError
    from cosim.scenario.checks import ScenarioError
    from cosim.scenario.spec import Scenario
    from cosim.study.spec import StudyError

    __version__: str  # the package's version, :mod:`cosim.version` (read at first use)

__all__ = [
    "CosimError", "Run", "RunError", "RunInterrupted", "SavedRun", "Scenario",
    "ScenarioError", "Study", "StudyError", "SweepInterrupted", "build_fmus",
    "load_scenario", "resume", "run", "sweep",
]  # fmt: skip
# where each name is defined, if not in cosim.api: the errors a caller catches and the
# Scenario load_scenario returns, exported here so that no caller names a module inside
_HOMES = {
    "CosimError": "cosim.errors",
    "Scenario": "cosim.scenario.spec",
    "ScenarioError": "cosim.scenario.checks",
    "StudyError": "cosim.study.spec",
}


# Type checkers see the names above, not these two: a module __getattr__ (typed to return
# Any) would make every misspelt name, ``cosim.rnu(...)``, an Any to a user's mypy --strict
# or pyright, and ``cosim.__version__`` an Any, not a str
if not TYPE_CHECKING:

    def __getattr__(name: str) -> Any:
        """The API's names, imported from :mod:`cosim.api` (or their own module, ``_HOMES``)
        at their first use; ``__version__``, the package's version (:mod:`cosim.version`)."""
        if name == "__version__":
            from cosim.version import version

            return version()
        if name in __all__:
            value = getattr(importlib.import_module(_HOMES.get(name, "cosim.api")), name)
            globals()[name] = value
            return value
        raise AttributeError(f"module 'cosim' has no attribute {name!r}")

    def __dir__() -> list[str]:
        """The API's names, not yet imported, ``__version__`` and the subpackages imported
        so far: ``cosim.<Tab>`` in IPython and Jupyter offers ``run``, ``load_scenario``,
        ... before their first use, and not this module's own imports (``Any``)."""
        own = {
            name
            for name, value in globals().items()
            if name.startswith("__") or getattr(value, "__name__", "") == f"cosim.{name}"
        }
        return sorted({*own, *__all__, "__version__"})
