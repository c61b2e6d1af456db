"""The pre-commit hook (``.pre-commit-config.yaml``) makes the checks CI makes (``.ci/run``,
CONTRIBUTING.md's "before a commit"), and makes them whenever what they check changes:
mypy and lint-imports check the whole project as ``pyproject.toml`` configures it, so a
commit changing only ``pyproject.toml`` (an import contract, a mypy setting) runs them too.

The files a hook is given are chosen as pre-commit chooses them (its ``Classifier``).
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from repo_paths import ROOT

yaml = pytest.importorskip("yaml", reason="pre-commit's own dependency (test extra)")
run = pytest.importorskip("pre_commit.commands.run", reason="needs pre-commit (test extra)")

CONFIG = yaml.safe_load((ROOT / ".pre-commit-config.yaml").read_text(encoding="utf-8"))
HOOKS = {hook["id"]: hook for repo in CONFIG["repos"] for hook in repo["hooks"]}


def _runs_on(hook: dict, changed: list[str]) -> list[str]:
    """The files of ``changed`` pre-commit hands ``hook`` (empty: the hook is skipped)."""
    classifier = run.Classifier.from_config(
        changed, CONFIG.get("files", ""), CONFIG.get("exclude", "^$")
    )
    view = SimpleNamespace(
        files=hook.get("files", ""),
        exclude=hook.get("exclude", "^$"),
        types=hook.get("types", ["file"]),
        types_or=hook.get("types_or", []),
        exclude_types=hook.get("exclude_types", []),
    )
    return list(classifier.filenames_for_hook(view))


def test_the_hook_makes_every_check_ci_makes() -> None:
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    for check in ("ruff check", "ruff format", "mypy", "lint-imports"):
        assert f"\n{check}" in ci, f".ci/run no longer runs {check}: update this test"
        assert any(hook["entry"].startswith(check) for hook in HOOKS.values()), check


@pytest.mark.parametrize("hook_id", ["mypy", "import-linter"])
@pytest.mark.parametrize(
    "changed", [["pyproject.toml"], ["cosim/runner.py"], ["plant_fmu/model/dynamics.py"]]
)
def test_a_whole_project_check_runs_when_its_code_or_its_configuration_changes(
    hook_id: str, changed: list[str]
) -> None:
    """A commit changing only ``[tool.importlinter]`` skipped lint-imports ("no files to
    check"): the broken contract reached CI."""
    hook = HOOKS[hook_id]
    assert hook.get("pass_filenames") is False  # it checks the project, not the files
    assert _runs_on(hook, changed), f"{hook_id} is skipped for a commit of {changed}"


def test_a_whole_project_check_skips_a_commit_of_prose_alone() -> None:
    for hook_id in ("mypy", "import-linter"):
        assert _runs_on(HOOKS[hook_id], ["README.md", "docs/model.md"]) == []
