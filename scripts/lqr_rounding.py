"""How far rounding moves the LQR autopilot's gain, and where two numpy installs part.

    python scripts/lqr_rounding.py [--save FILE] [--against FILE] [--trials N]

1. The design of lqr-1's autopilot (remus100 at U0 = 1.525 m/s, 10 ms, the dissertation's
   weights: ``controller_fmu/lqr.py``): the condition numbers of the linear systems its
   Riccati solve hands to ``np.linalg.solve``, and how far the gain K moves when each of
   those solutions is perturbed by about one unit in the last place (``--trials`` seeded
   trials): the rounding the design cannot resolve, whatever the install.
2. ``--save FILE``: the design's matrices bit for bit (A, B, their zero-order hold Ad, Bd,
   the Riccati solution X, the gain K) as JSON, with this install's numpy and Python.
3. ``--against FILE``: each of them compared with a file saved under another install:
   "bit for bit", or the largest difference relative to the largest entry.

docs/performance.md#other-pythons quotes its figures (numpy 2.4.6 against 2.5.5).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from unittest import mock

import numpy as np

from controller_fmu import riccati
from controller_fmu.lateral_model import LateralDesignModel
from controller_fmu.lqr import state_weight
from controller_fmu.lqr_weights import DISSERTATION_Q_Y, DISSERTATION_R_U
from controller_fmu.matrix_exponential import zero_order_hold
from plant_fmu.model.parameters import load_vehicle

DESIGN_SPEED = 1.525  # m/s, U0 of the built-in LQR scenarios
SAMPLE_TIME = 0.01  # s, their design_step


def design() -> dict[str, np.ndarray]:
    """A, B, Ad, Bd, X and K of the built-in LQR autopilot's design."""
    A, B = LateralDesignModel(load_vehicle("remus100"), DESIGN_SPEED).linearize()
    Ad, Bd = zero_order_hold(A, B, SAMPLE_TIME)
    K, X, _ = riccati.dlqr(Ad, Bd, state_weight(DISSERTATION_Q_Y), DISSERTATION_R_U)
    return {"A": A, "B": B, "Ad": Ad, "Bd": Bd, "X": X, "K": K}


def _with_solve(solve: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """K designed with ``solve`` in place of np.linalg.solve (put back afterwards)."""
    with mock.patch.object(np.linalg, "solve", solve):
        return design()["K"]


def sensitivity(trials: int) -> str:
    """The solves' condition numbers and the gain's spread under one-ulp perturbations
    of each solve's solution, in words."""
    original = np.linalg.solve
    conditions: list[float] = []

    def counted(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        conditions.append(float(np.linalg.cond(a)))
        return original(a, b)

    reference = _with_solve(counted)
    rng = np.random.default_rng(1)
    ulp = float(np.finfo(float).eps)

    def perturbed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        x = original(a, b)
        return x * (1.0 + ulp * rng.uniform(-1.0, 1.0, np.shape(x)))

    moves = [
        float(np.max(np.abs(_with_solve(perturbed) - reference)) / np.max(np.abs(reference)))
        for _ in range(trials)
    ]
    return (
        f"{len(conditions)} solves, condition numbers up to {max(conditions):.2g} (median "
        f"{float(np.median(conditions)):.2g}); each solution perturbed by one ulp: K moves "
        f"{float(np.median(moves)):.2g} (median), {max(moves):.2g} (largest) of its largest "
        f"entry in {trials} trials"
    )


def compare(mine: dict[str, np.ndarray], saved: dict[str, list[str]]) -> list[str]:
    """One line per matrix: "bit for bit" or its largest relative difference."""
    lines = []
    for name, matrix in mine.items():
        theirs = np.array([float.fromhex(v) for v in saved[name]]).reshape(matrix.shape)
        if np.array_equal(matrix, theirs):
            lines.append(f"  {name}: bit for bit")
        else:
            apart = float(np.max(np.abs(matrix - theirs)) / np.max(np.abs(matrix)))
            lines.append(f"  {name}: {apart:.2g} apart (relative to the largest entry)")
    return lines


def main() -> int:
    """Parse the command line, print the sensitivity, save and compare as asked."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--save", type=Path, metavar="FILE")
    parser.add_argument("--against", type=Path, metavar="FILE")
    parser.add_argument("--trials", type=int, default=40)
    args = parser.parse_args()
    here = f"numpy {np.__version__}, Python {sys.version.split()[0]}"
    print(f"{here}: {sensitivity(args.trials)}")
    mine = design()
    if args.save:
        saved = {name: [v.hex() for v in m.ravel().tolist()] for name, m in mine.items()}
        args.save.write_text(json.dumps({"install": here, **saved}), encoding="utf-8")
    if args.against:
        other = json.loads(args.against.read_text(encoding="utf-8"))
        print(f"against {other['install']}:")
        print("\n".join(compare(mine, other)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
