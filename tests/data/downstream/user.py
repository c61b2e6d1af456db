"""A downstream user's script on cosim's public API (``cosim.__all__`` and docs/api.md's
examples), which ``mypy --strict`` must pass: tests/cosim/test_api_typing.py checks it.
It is type-checked only, never run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rerun.notebook import Viewer

import cosim
import cosim.viz.notebook
from cosim import (
    CosimError,
    Run,
    RunError,
    RunInterrupted,
    Scenario,
    ScenarioError,
    Study,
    StudyError,
    SweepInterrupted,
    build_fmus,
    load_scenario,
    resume,
    run,
    sweep,
)


def version() -> str:
    """The installed package's version, a str (``auv-cosim --version``)."""
    return cosim.__version__


def completed(done: Run) -> bool:
    """Whether the run reached its stop time."""
    return done.complete


def out_folder(done: Run) -> Path | None:
    """The run's folder, None for a run kept in memory."""
    return done.out_dir


def changed_scenario() -> Scenario:
    """docs/api.md, "Change a scenario": a loaded scenario with other settings."""
    scenario = load_scenario("bs-3").with_start({"plant.u_0": 1.2, "controller.k0": 0.3})
    scenario = scenario.with_overrides(stop_time=2.0, algorithm="jacobi", extrapolation="linear")
    return scenario.with_debug_logging({"plant": []})


def runs() -> list[Run]:
    """docs/api.md, "Run a scenario" and "Keep the run folder"."""
    first = cosim.run("bs-3", stop_time=5.0, start={"plant.v_0": np.float32(-0.05)})
    kept = run(
        changed_scenario(),
        stop_time=np.int64(3),
        algorithm="gauss-seidel",
        extrapolation="quadratic",
        tolerance=1e-3,
        check_step=True,
        out="runs/bs-3-kept",
        overwrite=True,
        recording=False,
        progress=np.bool_(False),  # a numpy bool counts as its value
        checkpoint_every=1.0,
    )
    return [first, kept, resume("runs/bs-3-kept", recording=np.False_)]


def kept_files() -> list[str]:
    """docs/api.md, "Keep the run folder": a run with ``out=`` (and a resumed one) has its
    folder, a Path, read with no ``assert run.out_dir is not None`` first."""
    kept = cosim.run("bs-3", stop_time=3.0, out="runs/bs-3-api", overwrite=True)
    resumed = resume("runs/bs-3-kept")
    folders: list[Path] = [kept.out_dir, resumed.out_dir]
    return sorted(p.name for folder in folders for p in folder.iterdir())


def maybe_kept(out: str | None) -> Path | None:
    """A wrapper passing on an optional folder: neither of run's variants alone takes
    ``str | None``; the call is typed as either's result, a Run, its folder optional."""
    return cosim.run("bs-3", stop_time=3.0, out=out).out_dir


def refused() -> str:
    """docs/api.md, "Errors": each error the API raises, as a user catches it."""
    try:
        run("bs-3", start={"plant.v_O": -0.05})
    except ScenarioError as error:
        return str(error)
    except RunError as error:
        partial: Run = error.run
        return repr(partial)
    except RunInterrupted as error:
        stopped: Run = error.run
        return repr(stopped)
    except CosimError as error:
        return str(error)
    return ""


def study() -> Study | None:
    """docs/api.md, "Studies"."""
    try:
        return sweep(
            {"scenario": "bs-3", "stop_time": 2.0, "grid": {"plant.v_0": [-0.1, 0.1]}},
            workers=1,
            oversubscribe=np.bool_(False),
            max_runs=10,
            fmu_log={"controller": ["logAutopilotLimits"]},
        )
    except StudyError:
        return None
    except SweepInterrupted as error:
        return error.study


def fmus() -> dict[str, Path]:
    """docs/api.md, "Build the FMUs"."""
    return build_fmus("build/fmus", force=np.False_)


def viewer(done: Run) -> Viewer:
    """docs/api.md, "Recordings in the browser": the run's recording in a notebook."""
    folder = done.out_dir or Path("runs/bs-3-api")
    return cosim.viz.notebook.inline_viewer(folder, height=400)
