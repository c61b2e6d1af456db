"""What to tell a user who names a run folder that is not there (``auv-cosim view`` and
``report``): the scenario id typed for its folder (``bs-3`` for ``runs/bs-3``), a
built-in scenario not run yet, with the command that runs it, or the run's own report
folder (``runs/bs-3/report``) for the run's."""

from __future__ import annotations

from pathlib import Path

from cosim.errors import did_you_mean_path
from cosim.outputs.run_files import REPORT_FOLDER, RESULTS_FILE
from cosim.paths import RUNS_DIR


def missing_run_hint(path: Path) -> str:
    """A hint in parentheses, with a leading space, for the run folder ``path`` that does
    not exist; ``""`` when it exists or nothing better than a guess at a typo is known.

    ``bs-3`` when ``runs/bs-3`` is a folder: `` (did you mean 'runs/bs-3'?)``; ``lqr-1`` or
    ``runs/lqr-1`` for a built-in scenario without a run there: the command that writes
    it; a run's report folder (``runs/bs-3/report``, what ``report`` writes): the run's
    folder; anything else: :func:`cosim.errors.did_you_mean_path`'s guess among its
    neighbours.
    """
    if path.name == REPORT_FOLDER and (path.parent / RESULTS_FILE).is_file():
        return f" (the report folder of a run: did you mean {str(path.parent)!r}?)"
    if path.exists():
        return ""
    name, default = path.name, RUNS_DIR / path.name
    if path == Path(name) and default.is_dir():
        return f" (did you mean {str(default)!r}?)"
    if path in (Path(name), default) and not default.exists() and _is_builtin(name):
        return f" (no run of {name} yet: `auv-cosim run {name}` writes {default})"
    return did_you_mean_path(path)


def _is_builtin(name: str) -> bool:
    """Whether ``name`` is a built-in scenario id (imported here: only a refusal asks)."""
    from cosim.scenario.spec import SCENARIO_FOLDER

    return bool(name) and (SCENARIO_FOLDER / f"{name}.toml").is_file()
