"""A downstream developer's ``mypy --strict`` on scripts calling cosim's public API
(docs/api.md, "Types"): the documented calls pass, the mistakes are its errors."""

from __future__ import annotations

import inspect
import json
import os
import re
import shutil
import sys
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import ROOT
from users_mypy import users_mypy

import cosim

DOWNSTREAM = ROOT / "tests" / "data" / "downstream"
ERROR_MARK = re.compile(r"# error: (.+)$")


def _expected_errors(script: Path) -> dict[int, str]:
    """Line number -> the start of the message mypy must give there (its ``# error:``)."""
    lines = script.read_text(encoding="utf-8").splitlines()
    found = {number: ERROR_MARK.search(line) for number, line in enumerate(lines, start=1)}
    return {number: match.group(1) for number, match in found.items() if match}


@pytest.mark.slow
def test_a_users_mypy_strict_passes_the_documented_calls_and_catches_the_mistakes(
    tmp_path: Path, users_mypy_cache: Path
) -> None:
    """``import cosim`` names each API function through a module ``__getattr__`` typed to
    return Any: a misspelt ``cosim.rnu("bs-3")`` was no error to a user's type checker, and
    ``cosim.__version__`` an Any that passed for an int. Every public name used as
    docs/api.md shows passes ``mypy --strict`` (user.py); each mistake in typos.py is an
    error at its line, and nothing else is."""
    user, typos = DOWNSTREAM / "user.py", DOWNSTREAM / "typos.py"
    report, status = users_mypy([user, typos], tmp_path, users_mypy_cache)
    errors = re.findall(r"^(.+?):(\d+): error: (.+)$", report, flags=re.MULTILINE)
    assert [e for e in errors if Path(e[0]).name != "typos.py"] == [], report
    given = {int(line): message for _, line, message in errors}
    for line, start in _expected_errors(typos).items():
        assert given.get(line, "").startswith(start), f"typos.py:{line}: {start}\n{report}"
    assert set(given) == set(_expected_errors(typos)), report
    assert status == 1, report


def _public_callables() -> dict[str, object]:
    """``cosim.__all__``'s functions and the Scenario methods docs/api.md shows."""
    named = {name: getattr(cosim, name) for name in cosim.__all__}
    found: dict[str, object] = {n: v for n, v in named.items() if inspect.isfunction(v)}
    for method in ("with_start", "with_overrides", "with_debug_logging"):
        found[f"Scenario.{method}"] = getattr(cosim.Scenario, method)
    return found


@pytest.mark.parametrize("name", sorted(_public_callables()))
def test_every_public_functions_help_says_what_it_raises(name: str) -> None:
    """help() and an IDE's hover show the docstring: each public call's says what it
    raises (``Scenario.with_overrides``' said nothing of its refusal, nor its units)."""
    doc = inspect.getdoc(_public_callables()[name]) or ""
    assert re.search(r"\bRaises\b", doc), f"{name}'s docstring names no exception"


@pytest.mark.slow
def test_pyright_knows_the_type_of_every_public_name() -> None:
    """pyright's ``--verifytypes`` (how a type checker sees a library's public names):
    the pydantic models' ``model_config`` left unannotated made every scenario model's
    base, and so ``Scenario``, ``cosim.load_scenario``, ``cosim.run`` and
    ``cosim.resume``, "partially unknown" to it."""
    pyright = shutil.which("pyright")
    if pyright is None:
        pytest.skip("pyright is not installed (pip install pyright): not in the test extras")
    command = [pyright, "--pythonpath", sys.executable, "--verifytypes", "cosim"]
    command += ["--ignoreexternal", "--outputjson"]
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}  # this checkout's cosim
    done = run_in_group(command, timeout=600, cwd=ROOT, env=environment)
    symbols = json.loads(done.stdout)["typeCompleteness"]["symbols"]
    public = {f"cosim.{name}" for name in cosim.__all__}
    found = {s["name"]: s["diagnostics"] for s in symbols if s["name"] in public}
    assert set(found) == public, sorted(public - set(found))
    assert {name: d for name, d in found.items() if d} == {}
