"""Does auv-cosim work with every direct dependency at the lowest version pyproject.toml
allows, as a user's environment of older libraries (a lab's image, a distribution's
packages) may hold them?

    python scripts/check_floors.py [--venv /tmp/floors-venv] [--stop-time SECONDS]
                                   [--fast-tier]

1. A fresh virtual environment of this Python at ``--venv`` (an earlier one there is
   replaced), with uv, and pyproject.toml's dependencies installed by uv at their floors
   (``--resolution lowest-direct``: each direct dependency at the lowest version its
   range allows). The project itself is not installed: it runs from this tree
   (``PYTHONPATH``), which the check leaves as it found it.
2. ``auv-cosim run bs-3 --no-rrd`` there and with this interpreter, each building the FMUs
   into a folder of its own (an FMU records the Python that built it): the two
   results.csv must be byte-identical.
3. A study of two short runs (``auv-cosim sweep``) there.
4. With ``--fast-tier``: the ``test`` extra at its floors too, and the fast tier of the
   suite there (``-m "not slow"``; many minutes).

Needs the package registry (pip's configuration for uv itself); a few minutes on 2 cores.
Exit status 0 when every step passed, 1 when one failed, 3 when the floors could not be
fetched (no registry); the reason is one line on stderr."""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
INSTALL_S = 900.0  # s: uv downloads a few hundred MB the first time
RUN_S = 900.0  # s: one run or the study, FMU build and numba's compiling included
STUDY = '[grid]\n"plant.v_0" = [-0.05, 0.05]\n'
UNAVAILABLE = 3  # the exit status where the registry cannot be reached


class FloorsUnavailableError(Exception):
    """The floors cannot be fetched here (no registry): nothing was checked."""


def floor_requirements(extras: tuple[str, ...] = ()) -> list[str]:
    """pyproject.toml's dependencies, and those of ``extras``, as requirement strings."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    found = list(project["dependencies"])
    for extra in extras:
        found += project["optional-dependencies"][extra]
    return found


def make_floors_venv(folder: Path) -> Path:
    """A fresh virtual environment of this Python at ``folder`` holding uv (pip); its
    Python's path. Raises ValueError where ``folder`` holds anything but a virtual
    environment, FloorsUnavailableError where pip cannot install uv."""
    if folder.exists() and not (folder / "pyvenv.cfg").is_file():
        raise ValueError(f"--venv {folder}: not a virtual environment, expected a new folder")
    shutil.rmtree(folder, ignore_errors=True)
    venv.create(folder, with_pip=True)
    python = folder / "bin" / "python"
    pip = [str(python), "-m", "pip", "install", "-q", "uv"]
    done = subprocess.run(pip, capture_output=True, text=True, timeout=INSTALL_S)
    if done.returncode != 0:
        raise FloorsUnavailableError(f"pip cannot install uv: {done.stderr.strip()[-500:]}")
    return python


def install_floors(python: Path, requirements: list[str]) -> None:
    """``requirements`` installed by uv into ``python``'s environment, each direct one at
    the lowest version it allows. Raises RuntimeError naming what does not resolve or
    install, FloorsUnavailableError where uv cannot reach the registry."""
    command = [str(python.parent / "uv"), "pip", "install", "--python", str(python)]
    command += ["--resolution", "lowest-direct", *requirements]
    done = subprocess.run(command, capture_output=True, text=True, timeout=INSTALL_S)
    said = done.stderr.strip()
    if done.returncode != 0:
        if "No solution found" in said or "Failed to build" in said:
            raise RuntimeError(f"the floors do not install: {said[-2000:]}")
        raise FloorsUnavailableError(f"uv cannot fetch the floors: {said[-500:]}")


def cosim(python: Path | str, args: list[str | Path], cwd: Path) -> None:
    """``python -m cosim args`` from this tree in ``cwd`` (no bytecode written); raises
    RuntimeError with the command's last words when it fails."""
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "PYTHONPATH": path, "PYTHONDONTWRITEBYTECODE": "1"}
    command = [str(python), "-m", "cosim", *map(str, args)]
    done = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=RUN_S)
    if done.returncode != 0:
        said = done.stderr.strip()[-2000:]
        raise RuntimeError(f"{' '.join(command[2:5])} by {python} failed: {said}")


def run_bs3(python: Path | str, folder: Path, stop_time: float | None) -> bytes:
    """results.csv of ``auv-cosim run bs-3 --no-rrd`` by ``python`` in ``folder`` (made),
    the FMUs built into ``folder/fmus``."""
    folder.mkdir(parents=True)
    args: list[str | Path] = ["run", "bs-3", "--no-rrd", "--quiet", "--out", folder / "run"]
    args += ["--fmu-dir", folder / "fmus"]
    if stop_time is not None:
        args += ["--stop-time", str(stop_time)]
    cosim(python, args, folder)
    return (folder / "run" / "results.csv").read_bytes()


def run_study(python: Path, folder: Path, stop_time: float) -> None:
    """``auv-cosim sweep`` of two short bs-3 runs by ``python`` in ``folder``, on the FMUs
    of ``folder/fmus``."""
    study = folder / "floors-study.toml"
    study.write_text(f'scenario = "bs-3"\nstop_time = {stop_time}\n{STUDY}')
    args: list[str | Path] = ["sweep", study, "--quiet", "--workers", "2"]
    args += ["--out", folder / "study", "--fmu-dir", folder / "fmus"]
    cosim(python, args, folder)


def fast_tier(python: Path) -> int:
    """The fast tier of the suite by ``python`` (its output shown); pytest's exit status."""
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "PYTHONPATH": path, "PYTHONDONTWRITEBYTECODE": "1"}
    command = [str(python), "-m", "pytest", "-q", "-n", "2", "-p", "no:cacheprovider"]
    return subprocess.run([*command, "-m", "not slow"], cwd=ROOT, env=env).returncode


def check(args: argparse.Namespace, work: Path) -> str:
    """Every step of the module's docstring in ``work``: "" when all passed, else what
    failed (one line)."""
    python = make_floors_venv(args.venv.absolute())
    install_floors(python, floor_requirements(("test",) if args.fast_tier else ()))
    ours = run_bs3(sys.executable, work / "here", args.stop_time)
    floors = run_bs3(python, work / "floors", args.stop_time)
    if floors != ours:
        return "bs-3's results.csv at the floors differs from this interpreter's"
    run_study(python, work / "floors", args.stop_time or 5.0)
    if args.fast_tier and fast_tier(python) != 0:
        return "the fast tier failed at the floors"
    return ""


def main() -> int:
    """Parse the command line, check, and say how it went."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    folder = Path(tempfile.gettempdir()) / "floors-venv"
    parser.add_argument("--venv", type=Path, default=folder, help=f"[{folder}]")
    parser.add_argument("--stop-time", type=float, default=None, help="s [bs-3's]")
    parser.add_argument("--fast-tier", action="store_true", help="also the fast tier")
    args = parser.parse_args()
    status = 1
    with tempfile.TemporaryDirectory(prefix="floors-") as work:
        try:
            problem = check(args, Path(work))
        except FloorsUnavailableError as exc:
            problem, status = str(exc), UNAVAILABLE
        except (RuntimeError, ValueError, subprocess.SubprocessError, OSError) as exc:
            problem = str(exc)
    if problem:
        print(f"check_floors: {' '.join(problem.split())}", file=sys.stderr)
        return status
    print(f"check_floors: bs-3 byte-identical and the study done at the floors ({args.venv})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
