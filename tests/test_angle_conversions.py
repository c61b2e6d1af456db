"""Every conversion between degrees and radians goes through one helper (math.degrees,
math.radians, numpy's degrees/radians/deg2rad/rad2deg): no hand-typed 180 / pi, pi / 180,
57.3 or 0.01745 that a slip (57.3 for 57.2958, 180 / pi where pi / 180 was meant) could
hide in."""

from __future__ import annotations

import ast
import math
from pathlib import Path

from repo_paths import ROOT

FOLDERS = ("cosim", "plant_fmu", "controller_fmu", "fmu_runtime", "scripts", "tests")
FACTORS = (math.degrees(1.0), math.radians(1.0))  # deg per rad, rad per deg
CLOSE = 2e-3  # relative: 57.3 and 0.01745 are hand-typed factors too


def _is_pi(node: ast.expr) -> bool:
    name = node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", None)
    return name == "pi"


def _is_180(node: ast.expr) -> bool:
    return isinstance(node, ast.Constant) and node.value in (180, 180.0)


def _hand_typed(node: ast.AST) -> bool:
    """A division of 180 by pi (or back), or a number within CLOSE of either factor."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
        return (_is_180(node.left) and _is_pi(node.right)) or (
            _is_pi(node.left) and _is_180(node.right)
        )
    if isinstance(node, ast.Constant) and isinstance(node.value, float):
        return any(abs(node.value - f) <= CLOSE * f for f in FACTORS)
    return False


def _offenders(paths: list[Path], root: Path = ROOT) -> list[str]:
    """path:line of every hand-typed factor in ``paths`` (named relative to ``root``)."""
    found = []
    for path in paths:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        found += [
            f"{path.relative_to(root)}:{node.lineno}"
            for node in ast.walk(tree)
            if _hand_typed(node)
        ]
    return found


def test_no_hand_typed_degree_radian_factor() -> None:
    paths = sorted(p for folder in FOLDERS for p in (ROOT / folder).rglob("*.py"))
    assert len(paths) > 100, "too few files found: the rule would not cover the code"
    offenders = _offenders(paths)
    assert not offenders, "deg/rad by hand (use math.degrees/radians): " + ", ".join(offenders)


def test_the_check_finds_each_hand_typed_form(tmp_path: Path) -> None:
    forms = ["180.0 / math.pi", "np.pi / 180", "57.3", "0.01745", "180 / pi"]
    for k, form in enumerate(forms):
        (tmp_path / f"m{k}.py").write_text(f"x = {form}\ny = math.degrees(1.0)\n")
    found = _offenders(sorted(tmp_path.glob("*.py")), tmp_path)
    assert len(found) == len(forms), found
