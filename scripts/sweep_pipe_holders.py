"""Who holds ``auv-cosim sweep``'s stderr after the command has exited, and for how long:
the end-to-end benchmark's study (``scripts/bench_sweep.py --end-to-end``) swept with its
stderr to a pipe, as a pipe reading the command waits for it (``| tee``, a CI log). For
each sweep: the seconds from the command's exit to the pipe's end of file, and each other
process that held the pipe after the exit (its command line), with the last time it was
seen holding it (from scans of ``/proc/*/fd``, Linux only, as fast as they go).

``--baseline REV`` sweeps that git revision too, alternating with this tree, so both see
the same load; with ``--workers 1 2`` each tree sweeps with 1 and with 2 workers.
Usage: ``python scripts/sweep_pipe_holders.py [--repeat 5] [--baseline main]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import NamedTuple

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sweep import ROOT, installed, installed_env, study_file, tree_at

from cosim.fmus.build import ensure_fmus


def holders(pipe: str, skip: int) -> dict[int, str]:
    """The processes (pid: command line) other than ``skip`` with an fd on ``pipe``."""
    found = {}
    for pid in filter(str.isdigit, os.listdir("/proc")):
        if int(pid) == skip:
            continue
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
            if any(os.readlink(f"/proc/{pid}/fd/{fd}") == pipe for fd in fds):
                line = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")
                found[int(pid)] = line.decode(errors="replace")[:90]
        except OSError:  # gone meanwhile
            continue
    return found


class Ending(NamedTuple):
    """One sweep's end: exit to end of file (s), the holders after the exit, exit code."""

    after: float
    holders: dict[int, tuple[str, float]]  # pid: (command line, last seen holding, s)
    code: int


def children(pid: int) -> dict[int, str]:
    """The children of ``pid`` (pid: command line): what the pipe's holders were."""
    found = {}
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            for child in task.read_text().split():
                line = Path(f"/proc/{child}/cmdline").read_bytes().replace(b"\0", b" ")
                found[int(child)] = line.decode(errors="replace")[:90]
        except OSError:
            continue
    return found


def sweep(study: Path, workers: int, site: Path, fmu_dir: Path) -> Ending:
    """One sweep: exit-to-EOF seconds and {pid: (command line, last seen after exit)}."""
    out = study.parent / f"out-{workers}"
    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, "-m", "cosim.cli", "sweep", str(study), "--workers", str(workers)]
    command += ["--out", str(out), "--fmu-dir", str(fmu_dir.resolve()), "--quiet"]
    read, write = os.pipe()
    pipe = os.readlink(f"/proc/self/fd/{read}")
    env = installed_env(os.environ, site)
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=write, cwd=site,
                               start_new_session=True, env=env)  # fmt: skip
    os.close(write)
    eof: dict[str, float] = {}

    def drain() -> None:
        while os.read(read, 65536):
            pass
        eof["t"] = time.perf_counter()

    reader = threading.Thread(target=drain)
    reader.start()
    ended: dict[str, float] = {}

    def reap() -> None:
        _, status, _ = os.wait4(process.pid, 0)
        ended["t"], ended["code"] = time.perf_counter(), os.waitstatus_to_exitcode(status)

    reaper = threading.Thread(target=reap)
    reaper.start()
    names: dict[int, str] = {}  # the command's children, named while they live
    try:
        while reaper.is_alive():
            names.update(children(process.pid))
            reaper.join(0.05)
    finally:
        if reaper.is_alive():
            os.killpg(process.pid, 9)
    exited, process.returncode = ended["t"], ended["code"]
    seen: dict[int, tuple[str, float]] = {}
    while reader.is_alive():
        for pid, line in holders(pipe, os.getpid()).items():
            seen[pid] = (names.get(pid, line), time.perf_counter() - exited)
    reader.join()
    os.close(read)
    return Ending(eof["t"] - exited, seen, int(ended["code"]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--stop-time", type=float, default=120.0)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--workers", type=int, nargs="+", default=[2])
    parser.add_argument("--baseline", help="a git revision to measure alternately")
    parser.add_argument("--fmu-dir", type=Path, default=ROOT / "build" / "fmus")
    args = parser.parse_args()
    ensure_fmus(args.fmu_dir)
    with tempfile.TemporaryDirectory(prefix="auv-cosim-holders-") as name:
        folder = Path(name)
        study = study_file(folder, args.runs, args.stop_time)
        trees = {"this tree": (installed(ROOT, folder / "site"), args.fmu_dir)}
        if args.baseline:
            base = installed(tree_at(args.baseline, folder / "base"), folder / "base-site")
            trees = {args.baseline: (base, folder / "base-fmus"), **trees}
        for site, fmu_dir in trees.values():
            sweep(study, 1, site, fmu_dir)  # warm-up: numba's cache, the disk cache
        afters: dict[tuple[str, int], list[float]] = {}
        for _ in range(args.repeat):  # alternating, so all see the same load
            for label, (site, fmu_dir) in trees.items():
                for workers in args.workers:
                    found = sweep(study, workers, site, fmu_dir)
                    afters.setdefault((label, workers), []).append(found.after)
                    load = os.getloadavg()[0]
                    print(f"{label}, {workers} worker(s): exit to EOF {found.after:.3f} s"
                          f"  (exit {found.code}, load {load:.1f})")  # fmt: skip
                    for pid, (line, last) in sorted(found.holders.items()):
                        print(f"    {pid}: held until >= {last:.3f} s  {line}")
    for (label, workers), values in afters.items():
        each = " ".join(f"{v:.3f}" for v in values)
        median = statistics.median(values)
        print(f"{label}, {workers} worker(s): exit to EOF median {median:.3f} s, {each}")


if __name__ == "__main__":
    main()
