"""The layering of the code, as docs/architecture.md states it and pyproject.toml checks it.

import-linter's contracts (``[tool.importlinter]`` in pyproject.toml) keep the imports
one-way; these tests keep the contracts, the code and the page describing them in step:
every room of ``cosim`` is in the layers contract and in the page's table, and the
contracts hold (the same check ``lint-imports`` makes in CI).
"""

from __future__ import annotations

import tomllib

import pytest
from repo_paths import ROOT

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
CONTRACTS = PYPROJECT["tool"]["importlinter"]["contracts"]
ARCHITECTURE = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")


def cosim_rooms() -> set[str]:
    """Every subpackage and module directly under cosim/ (``cosim.engine``, ``cosim.cli``)."""
    folder = ROOT / "cosim"
    rooms = {p.name for p in folder.iterdir() if (p / "__init__.py").is_file()}
    rooms |= {p.stem for p in folder.glob("*.py") if p.name != "__init__.py"}
    return {f"cosim.{room}" for room in rooms}


def layered_rooms() -> set[str]:
    (layers,) = [c["layers"] for c in CONTRACTS if c["type"] == "layers"]
    return {room.strip() for layer in layers for room in layer.split("|")}


def test_every_room_of_cosim_is_in_the_layers_contract() -> None:
    missing = cosim_rooms() - layered_rooms()
    assert not missing, f"rooms of cosim outside the layers contract in pyproject.toml: {missing}"


def test_every_layered_room_exists() -> None:
    stale = layered_rooms() - cosim_rooms()
    assert not stale, f"the layers contract names rooms that do not exist: {stale}"


def test_the_architecture_page_describes_every_room() -> None:
    undescribed = {
        room
        for room in cosim_rooms()
        if f"`{room.replace('.', '/')}/`" not in ARCHITECTURE
        and f"`{room.replace('.', '/')}.py`" not in ARCHITECTURE
    }
    assert not undescribed, f"docs/architecture.md does not describe {sorted(undescribed)}"


def test_the_import_contracts_hold() -> None:
    """What ``lint-imports`` checks in CI, here too (a broken layer fails the fast tier)."""
    cli = pytest.importorskip("importlinter.cli")
    assert cli.lint_imports(config_filename=str(ROOT / "pyproject.toml")) == 0


def test_the_architecture_page_states_the_layers_as_the_contract_does() -> None:
    """The page's block of layers, top to bottom, is the layers contract line by line (it
    lost ``cosim.whole_file`` while saying "as pyproject.toml states them")."""
    block = ARCHITECTURE.split("as pyproject.toml states them -->", 1)[1]
    block = block.split("```text\n", 1)[1].split("```", 1)[0]
    page = [line.split("(", 1)[0].strip() for line in block.splitlines()]
    (layers,) = [c["layers"] for c in CONTRACTS if c["type"] == "layers"]
    assert page == layers
