"""The suite's warning policy (CONTRIBUTING.md#warnings-from-the-libraries): a library's
deprecation that points at our code fails the test, one raised inside a library does not.

CI installs the newest release each range of pyproject.toml allows, so a release that
deprecates an API we call fails CI on purpose; one that deprecates an API a library calls
in another must not fail it, since nothing of ours can be changed for it."""

from __future__ import annotations

import tomllib
import warnings

import pytest
from _pytest.config import parse_warning_filter
from repo_paths import ROOT

DEPRECATIONS = (DeprecationWarning, PendingDeprecationWarning, FutureWarning)


def _emit_under_the_suites_filters(category: type[Warning], module: str) -> None:
    """Warn as a library does of its caller (warn's stacklevel names the caller's module:
    ``module``), with pyproject.toml's ``filterwarnings`` in force as pytest puts them."""
    ini = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    entries = ini["tool"]["pytest"]["ini_options"].get("filterwarnings", [])
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        for entry in entries:
            warnings.filterwarnings(*parse_warning_filter(entry, escape=False))
        warnings.warn_explicit(
            "old_api() is deprecated; use new_api()", category, f"{module}.py", 1, module=module
        )


@pytest.mark.parametrize("category", DEPRECATIONS)
@pytest.mark.parametrize(
    "module",
    ["cosim.engine.master", "cosim", "plant_fmu.model.dynamics", "controller_fmu.riccati",
     "fmu_runtime.safe_slave", "test_margins", "conftest"],
)  # fmt: skip
def test_a_deprecation_pointing_at_our_code_fails_the_test(
    category: type[Warning], module: str
) -> None:
    with pytest.raises(category, match="old_api"):
        _emit_under_the_suites_filters(category, module)


@pytest.mark.parametrize("category", DEPRECATIONS)
@pytest.mark.parametrize(
    "module", ["pandas.core.frame", "control.statesp", "distributed.worker", "cosimpy", "tests_x"]
)
def test_a_deprecation_raised_inside_a_library_stays_a_warning(
    category: type[Warning], module: str
) -> None:
    with pytest.warns(category, match="old_api"):
        _emit_under_the_suites_filters(category, module)
