"""A built-in scenario copied to a file of one's own, to edit and run
(``auv-cosim scenarios --copy ID FILE``): the file as shipped, comments and all, written
whole; never over an existing file, which may hold someone's edits."""

from __future__ import annotations

import shutil
from pathlib import Path

from cosim.errors import did_you_mean
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import SCENARIO_FOLDER, builtin_scenarios
from cosim.whole_file import write_whole


def copy_builtin(scenario_id: str, dest: Path) -> Path:
    """Copy the built-in scenario ``scenario_id`` to ``dest`` (a new ``.toml`` file) and
    return ``dest``. Raises :class:`ScenarioError` for an unknown id (naming the likely
    one), a name without ``.toml`` (a run would read it as an id) or an existing ``dest``."""
    ids = builtin_scenarios()
    if scenario_id not in ids:
        raise ScenarioError(
            f"unknown scenario {scenario_id!r}{did_you_mean(scenario_id, ids)}: expected a "
            f"built-in id ({', '.join(ids)})"
        )
    if dest.suffix != ".toml":
        raise ScenarioError(
            f"cannot copy {scenario_id} to {dest}: expected a file name ending in .toml "
            "(`auv-cosim run` reads a name without it as a built-in id)"
        )
    if dest.exists() or dest.is_symlink():
        raise ScenarioError(
            f"{dest} exists: copying {scenario_id} there would write over it; give another "
            "file name, or remove it first"
        )
    if not dest.parent.is_dir():
        raise ScenarioError(
            f"cannot copy {scenario_id} to {dest}: the folder {dest.parent} does not exist"
        )
    source = SCENARIO_FOLDER / f"{scenario_id}.toml"
    try:
        write_whole(dest, lambda tmp: shutil.copyfile(source, tmp))
    except OSError as exc:
        raise ScenarioError(f"cannot copy {scenario_id} to {dest}: {exc.strerror}") from None
    return dest
