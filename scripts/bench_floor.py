"""The FMI floor's FMUs, built for a benchmark: the trivial pythonfmu pair of our interface
shape, which scripts/bench_cosim.py and scripts/bench_loader.py measure our loops against.
Both sides come from one definition, ``bench_fmus/bench_trivial.py``."""

from __future__ import annotations

import re
from pathlib import Path

from cosim.fmus.build import pythonfmu_build

DEFINITION = Path(__file__).resolve().parent / "bench_fmus" / "bench_trivial.py"
SIDES = {"Controller": (20, 8), "Plant": (8, 20)}  # Real inputs, outputs: our FMUs' shapes
_SHAPE = re.compile(r"^N_INPUTS, N_OUTPUTS = \d+, \d+", re.MULTILINE)
_CLASS = "class BenchTrivial("


def side_script(side: str) -> str:
    """The script of the FMU ``BenchTrivial<side>``: the definition, its class named after
    the side and its shape the side's (:data:`SIDES`)."""
    text = DEFINITION.read_text(encoding="utf-8")
    if len(_SHAPE.findall(text)) != 1 or text.count(_CLASS) != 1:
        raise SystemExit(f"{DEFINITION}: expected one {_SHAPE.pattern!r} line and one {_CLASS}")
    n_inputs, n_outputs = SIDES[side]
    text = _SHAPE.sub(f"N_INPUTS, N_OUTPUTS = {n_inputs}, {n_outputs}", text)
    return text.replace(_CLASS, f"class BenchTrivial{side}(")


def floor_fmus(folder: Path) -> list[Path]:
    """The trivial pair built into ``folder`` (their scripts written to ``folder/scripts``):
    the controller, then the plant."""
    scripts = folder / "scripts"
    scripts.mkdir(exist_ok=True)
    fmus = []
    for side in SIDES:
        script = scripts / f"bench_trivial_{side.lower()}.py"
        script.write_text(side_script(side), encoding="utf-8")
        fmus.append(pythonfmu_build(script, folder, f"BenchTrivial{side}"))
    return fmus
