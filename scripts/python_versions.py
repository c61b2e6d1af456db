"""auv-cosim under other Pythons: does it install, run, and give this Python's results?

    python scripts/python_versions.py PYTHON [PYTHON ...] [--work /tmp/python-versions]
                                      [--pin REQUIREMENT ...]

For each PYTHON (a CPython's executable, e.g. /root/.pyenv/versions/3.13.0/bin/python):

1. a fresh virtual environment in ``--work`` (an earlier one of that Python there is
   replaced) and ``pip install`` of this tree into it, as a user installs it, timed (wall
   clock and the CPU of pip's processes), then each ``--pin`` (``numpy==2.4.6``: this
   Python's release of a library, to tell the Python's part in a difference from the
   library's), with the releases installed of the libraries that compute (numpy, scipy,
   numba, llvmlite);
2. ``auv-cosim run SCENARIO --no-rrd`` there for bs-3, vert-1 and lqr-1 (a backstepping,
   a depth and an LQR autopilot), from ``--work`` so that the installed copy runs, each
   building its FMUs into a folder of its own, and the same runs by this interpreter from
   this tree: each results.csv "byte-identical" to this interpreter's, or the largest
   difference of any column at any time relative to that column's largest magnitude.

Needs the package registry (pip's configuration); minutes per Python on 2 cores.
Exit status 0 when every Python installed and ran, 1 when one did not."""

from __future__ import annotations

import argparse
import csv
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("bs-3", "vert-1", "lqr-1")
LIBRARIES = ("numpy", "scipy", "numba", "llvmlite")
INSTALL_S = 1800.0  # s: pip downloads a few hundred MB the first time
RUN_S = 900.0  # s: one run, its FMU build and numba's compiling included


def run(
    command: list[str | Path], cwd: Path, env: dict[str, str] | None = None, limit: float = RUN_S
) -> str:
    """``command``'s stdout; raises RuntimeError with its last words when it fails."""
    done = subprocess.run(
        [str(part) for part in command],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=limit,
    )  # fmt: skip
    if done.returncode != 0:
        said = (done.stderr.strip() or done.stdout.strip())[-1500:]
        raise RuntimeError(f"{' '.join(map(str, command[:4]))} failed: {said}")
    return done.stdout


def install(python: Path, venv: Path, pins: list[str]) -> tuple[Path, str]:
    """A fresh virtual environment of ``python`` at ``venv`` with this tree installed, then
    ``pins``; its Python and a line saying how long the install took and what it holds."""
    shutil.rmtree(venv, ignore_errors=True)
    run([python, "-m", "venv", venv], ROOT)
    inside = venv / "bin" / "python"
    run([inside, "-m", "pip", "install", "--quiet", "--upgrade", "pip"], ROOT)
    cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    run([inside, "-m", "pip", "install", "--quiet", ROOT], venv, limit=INSTALL_S)
    wall = time.monotonic() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    used = after.ru_utime - cpu.ru_utime + after.ru_stime - cpu.ru_stime
    if pins:
        run([inside, "-m", "pip", "install", "--quiet", *pins], venv, limit=INSTALL_S)
    show = "import importlib.metadata as m, sys; print(sys.version.split()[0], "
    show += "*(m.version(name) for name in sys.argv[1:]))"
    version, *releases = run([inside, "-c", show, *LIBRARIES], venv).split()
    chose = ", ".join(
        f"{name} {release}" for name, release in zip(LIBRARIES, releases, strict=True)
    )
    return (
        inside,
        f"Python {version}: pip install {wall:.0f} s wall clock, {used:.0f} s CPU; {chose}",
    )


def results(python: Path | str, scenario: str, folder: Path, from_tree: bool) -> Path:
    """results.csv of ``auv-cosim run scenario --no-rrd`` by ``python`` in ``folder``
    (made): this tree's copy when ``from_tree``, else the one installed beside it."""
    folder.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("PYTHONPATH", None)
    if from_tree:
        env["PYTHONPATH"] = str(ROOT)
    out = folder / scenario
    command: list[str | Path] = [python, "-m", "cosim", "run", scenario, "--no-rrd", "--quiet"]
    run([*command, "--out", out, "--overwrite", "--fmu-dir", folder / "fmus"], folder, env)
    return out / "results.csv"


def compare(ours: Path, theirs: Path) -> str:
    """ "byte-identical", or the largest difference of any column at any row relative to
    that column's largest magnitude in ``ours``, with the column's name."""
    if ours.read_bytes() == theirs.read_bytes():
        return "byte-identical"
    with ours.open() as a, theirs.open() as b:
        mine, other = list(csv.reader(a)), list(csv.reader(b))
    if mine[0] != other[0] or len(mine) != len(other):
        return "different columns or rows"
    worst, where = 0.0, mine[0][0]
    for column, name in enumerate(mine[0]):
        values = [
            (float(x[column]), float(y[column])) for x, y in zip(mine[1:], other[1:], strict=True)
        ]
        scale = max(abs(x) for x, _ in values) or 1.0
        difference = max(abs(x - y) for x, y in values) / scale
        if difference > worst:
            worst, where = difference, name
    return f"largest relative difference {worst:.1e} ({where})"


def main() -> int:
    """Parse the command line, check each Python, and say how it went."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("pythons", nargs="+", type=Path, metavar="PYTHON")
    parser.add_argument("--work", type=Path, default=Path("/tmp/python-versions"))
    parser.add_argument("--pin", action="append", default=[], metavar="REQUIREMENT")
    args = parser.parse_args()
    work = args.work.absolute()
    here = work / "this-python"
    ours = {name: results(sys.executable, name, here, from_tree=True) for name in SCENARIOS}
    print(f"this Python {sys.version.split()[0]} from this tree: the reference")
    failed = False
    for number, python in enumerate(args.pythons):
        try:
            inside, said = install(python, work / f"venv-{number}", args.pin)
            print(said, flush=True)
            for name in SCENARIOS:
                theirs = results(inside, name, work / f"runs-{number}", from_tree=False)
                print(f"  {name}: {compare(ours[name], theirs)}", flush=True)
        except (RuntimeError, subprocess.TimeoutExpired) as exc:
            print(f"{python}: {exc}", flush=True)
            failed = True
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
