"""What ``pip install .`` costs: the time it takes and the size of the environment it makes,
for this tree and for an earlier commit, side by side.

How it measures. Offline (the default), so that the network does not dominate: every
wheel either tree needs is first collected into a local wheelhouse (``pip wheel``, from the
package index or pip's cache; not timed), and each install runs as ``pip install
--no-index --find-links WHEELHOUSE PROJECT``. With ``--from-index``, as a user's first
install does: ``pip install --no-cache-dir PROJECT``, every wheel downloaded from the
package index each time (timed with the downloads). Either way each install runs in a
fresh virtual environment (``python -m venv``; timed, wall clock: resolving, downloading,
building our own wheel, unpacking, compiling bytecode); the size is the bytes of every file
in the environment afterwards. The trees are installed in turn, ``--rounds`` times, so the
machine's other load (and the network's speed) hits both alike; the best time is kept.

Prints every install as it ends, with the load average when it started; then per tree:
install time (wall clock, and the CPU time of pip's processes, which the machine's other
load disturbs less), environment size (MB, 1e6 bytes), the largest packages, and the
differences; then the load average.

Usage: python scripts/bench_install.py [--baseline REV] [--extras EXTRAS] [--rounds 2]
       [--wheelhouse DIR | --from-index]
(REV defaults to where HEAD left ``main``; the tree measured is the working tree holding
this script, its uncommitted changes included.)
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parents[1]
MB = 1e6


def _run(*command: str | Path, cwd: Path | None = None) -> None:
    subprocess.run([str(c) for c in command], check=True, cwd=cwd, stdout=subprocess.DEVNULL)


def _tree_at(revision: str, folder: Path) -> Path:
    """The repository's files at ``revision`` in ``folder`` (git archive)."""
    archive = folder / "tree.tar"
    with archive.open("wb") as out:
        subprocess.run(["git", "archive", revision], cwd=ROOT, stdout=out, check=True)
    tree = folder / "tree"
    with tarfile.open(archive) as tar:
        tar.extractall(tree, filter="data")
    return tree


def _working_tree(folder: Path) -> Path:
    """The working tree's files (tracked and new, as they are now, nothing git ignores) in
    ``folder``: pip builds in the source tree, which must not litter this one."""
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
        cwd=ROOT, check=True, capture_output=True, text=True,
    ).stdout.split("\0")  # fmt: skip
    for name in filter(None, listed):
        source = ROOT / name
        if source.is_file():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, folder / name)
    return folder


def _size(folder: Path) -> tuple[int, dict[str, int]]:
    """(bytes of every file under ``folder``, bytes per top-level entry of site-packages)."""
    total, per_package = 0, dict[str, int]()
    for directory, _, files in os.walk(folder):
        sizes = sum(os.lstat(os.path.join(directory, f)).st_size for f in files)
        total += sizes
        parts = Path(directory).relative_to(folder).parts
        if "site-packages" in parts:
            below = parts[parts.index("site-packages") + 1 :]
            key = below[0] if below else "(files)"
            per_package[key] = per_package.get(key, 0) + sizes
    return total, per_package


class Install(NamedTuple):
    """One install: wall clock and CPU time (its processes' user + system), s; bytes of
    the environment and per package; the 1-minute load average when it started."""

    seconds: float
    cpu_seconds: float
    size: int
    packages: dict[str, int]
    load: float


def _cpu_of_children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _install(project: str, source: list[str], folder: Path) -> Install:
    """One install into a fresh environment, from the wheels ``source`` names (pip's
    options: a wheelhouse, or the package index without pip's cache)."""
    venv = folder / "venv"
    shutil.rmtree(venv, ignore_errors=True)
    _run(sys.executable, "-m", "venv", venv)
    load = os.getloadavg()[0]
    cpu, start = _cpu_of_children(), time.perf_counter()
    _run(venv / "bin" / "python", "-m", "pip", "install", "--quiet", *source, project)
    seconds, cpu = time.perf_counter() - start, _cpu_of_children() - cpu
    total, packages = _size(venv)
    shutil.rmtree(venv)
    return Install(seconds, cpu, total, packages, load)


def _print_dropped(before: dict[str, int], after: dict[str, int], wheelhouse: Path | None) -> None:
    """The packages the baseline installs and this tree does not, with the size of their
    wheels if they were collected (what a download over the network no longer fetches)."""
    for name in sorted(set(before) - set(after)):
        if name.endswith((".dist-info", ".pth")) or name.startswith(("_", "(")):
            continue
        wheels = [] if wheelhouse is None else wheelhouse.glob("*.whl")
        size = " + ".join(
            f"; {w.name} {w.stat().st_size / MB:.1f} MB"
            for w in wheels
            if w.name.lower().startswith(f"{name}-")
        )
        print(f"only in the baseline: {name} {before[name] / MB:.0f} MB installed{size}")


def _parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--baseline", help="git revision to compare with (default: where HEAD left main)"
    )
    parser.add_argument("--extras", default="", help="extras to install, e.g. 'zig'")
    parser.add_argument("--rounds", type=int, default=2)
    source = parser.add_mutually_exclusive_group()
    source.add_argument(
        "--wheelhouse",
        type=Path,
        default=Path.home() / ".cache" / "auv-cosim" / "bench-install-wheels",
        help="where the wheels are collected for the offline installs",
    )
    source.add_argument(
        "--from-index",
        action="store_true",
        help="install from the package index with --no-cache-dir (downloads timed)",
    )
    args = parser.parse_args()
    if args.from_index:
        args.wheelhouse = None
    if not args.baseline:
        args.baseline = subprocess.run(
            ["git", "merge-base", "HEAD", "main"],
            cwd=ROOT,
            check=True,
            capture_output=True,
            text=True,
        ).stdout.strip()[:10]
    return args


def _measure(args: argparse.Namespace, suffix: str) -> dict[str, list[Install]]:
    """``--rounds`` installs of the baseline and of this tree, in turn, each printed."""
    with tempfile.TemporaryDirectory(prefix="auv-cosim-install-") as tmp:
        base = Path(tmp)
        (base / "baseline").mkdir()
        (base / "current").mkdir()
        trees = {
            f"{args.baseline} (baseline)": _tree_at(args.baseline, base / "baseline"),
            "this tree": _working_tree(base / "current"),
        }
        source = ["--no-cache-dir"]
        if args.wheelhouse is not None:
            args.wheelhouse.mkdir(parents=True, exist_ok=True)
            for tree in trees.values():  # collect the wheels (not timed)
                _run(sys.executable, "-m", "pip", "wheel", "--quiet", "--wheel-dir",
                     args.wheelhouse, f"{tree}{suffix}", "setuptools>=77")  # fmt: skip
            source = ["--no-index", "--find-links", str(args.wheelhouse)]
        results: dict[str, list[Install]] = {name: [] for name in trees}
        for round_ in range(1, args.rounds + 1):
            for name, tree in trees.items():
                run = _install(f"{tree}{suffix}", source, base)
                results[name].append(run)
                print(
                    f"round {round_}, {name}: {run.seconds:.1f} s wall clock, "
                    f"{run.cpu_seconds:.1f} s CPU, {run.size / MB:.0f} MB (load {run.load:.2f})",
                    flush=True,
                )
    return results


def main() -> None:
    args = _parse_args()
    suffix = f"[{args.extras}]" if args.extras else ""
    results = _measure(args, suffix)
    how = "from the index, no cache" if args.from_index else "offline"
    best = {}
    for name, runs in results.items():
        wall, cpu = min(r.seconds for r in runs), min(r.cpu_seconds for r in runs)
        best[name] = (wall, cpu, runs[-1].size)
        largest = sorted(runs[-1].packages.items(), key=lambda item: -item[1])[:8]
        print(
            f"{name}: pip install .{suffix} ({how}) {wall:.1f} s wall clock, {cpu:.1f} s CPU "
            f"(best of {len(runs)}), environment {runs[-1].size / MB:.0f} MB"
        )
        print("  largest: " + ", ".join(f"{p} {b / MB:.0f} MB" for p, b in largest))
    before, after = (runs[-1].packages for runs in results.values())
    _print_dropped(before, after, args.wheelhouse)
    (w0, c0, s0), (w1, c1, s1) = best.values()
    print(
        f"difference: {w0 - w1:.1f} s wall clock ({w1 / w0:.2f}x), {c0 - c1:.1f} s CPU "
        f"({c1 / c0:.2f}x), {(s0 - s1) / MB:.0f} MB ({s1 / s0:.2f}x)"
    )
    load = os.getloadavg()
    print(f"load average: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


if __name__ == "__main__":
    main()
