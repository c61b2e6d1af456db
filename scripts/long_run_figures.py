"""A long run's figures (docs/runs.md, "Long runs"): its files' sizes and its memory, and
those of a resume from half way.

Runs ``auv-cosim run SCENARIO --stop-time T`` (bs-3 for 21600 s: 6 h at 10 ms, 2.16
million rows) in fresh processes, each in a process group of its own: without a recording
(``--no-rrd``), with one, and with ``--no-rrd --checkpoint-every T/4`` stopped by SIGTERM
once results.csv holds half the rows (a checkpoint there), then resumed. For each it prints
the process's peak resident set size (the kernel's ``ru_maxrss``, ``os.wait4``), its CPU
time (user + system), results.csv's and recording.rrd's size and bytes per row.

Usage: python scripts/long_run_figures.py [--stop-time 21600] [--scenario bs-3]
       [--fmu-dir build/fmus] [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cosim.paths import DEFAULT_FMU_DIR


def run(command: list[str], stop_at: tuple[Path, int] | None = None) -> tuple[float, float]:
    """(peak RSS in MB, CPU s) of one ``auv-cosim`` process; ``stop_at`` (a file and a size in
    bytes): SIGTERM once the file is that large. Raises SystemExit if it fails."""
    with tempfile.TemporaryFile() as errors:
        proc = subprocess.Popen(
            [sys.executable, "-m", "cosim.cli", *command],
            stdout=subprocess.DEVNULL,
            stderr=errors,
            start_new_session=True,
        )
        try:
            while stop_at is not None and proc.poll() is None:
                path, size = stop_at
                if path.exists() and path.stat().st_size >= size:
                    os.killpg(proc.pid, signal.SIGTERM)
                    break
                time.sleep(0.2)
            _, status, usage = os.wait4(proc.pid, 0)
        except BaseException:  # (Ctrl-C here) the run's whole group ends with this script
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            raise
        code = os.waitstatus_to_exitcode(status)
        if code not in (0, 128 + signal.SIGTERM):
            errors.seek(0)
            raise SystemExit(f"{' '.join(command)} failed: {errors.read().decode()}")
    return usage.ru_maxrss / 1024.0, usage.ru_utime + usage.ru_stime


def sizes(folder: Path, rows: int) -> str:
    """results.csv's and recording.rrd's sizes in ``folder``, and their bytes per row."""
    shown = []
    for name in ("results.csv", "recording.rrd"):
        path = folder / name
        if path.exists():
            size = path.stat().st_size
            shown.append(f"{name} {size / 1e6:.0f} MB ({size / rows:.0f} B/row)")
    return ", ".join(shown)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop-time", type=float, default=21600.0)
    parser.add_argument("--scenario", default="bs-3")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    parser.add_argument("--out", type=Path, default=None, help="[a temporary folder]")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        out = args.out or Path(scratch)
        common = [args.scenario, "--stop-time", repr(args.stop_time), "--quiet", "--overwrite"]
        common += ["--fmu-dir", str(args.fmu_dir)]
        rows = None
        for label, options in (("no recording", ["--no-rrd"]), ("recording", [])):
            folder = out / label.replace(" ", "-")
            peak, cpu = run(["run", *common, "--out", str(folder), *options])
            rows = sum(1 for _ in (folder / "results.csv").open("rb")) - 1
            print(f"{label}: {rows} rows, peak RSS {peak:.0f} MB, CPU {cpu:.0f} s, "
                  f"{sizes(folder, rows)}")  # fmt: skip
        assert rows is not None
        folder = out / "resumed"
        half = (out / "no-recording" / "results.csv").stat().st_size // 2
        every = repr(args.stop_time / 4)
        peak, cpu = run(
            ["run", *common, "--out", str(folder), "--no-rrd", "--checkpoint-every", every],
            stop_at=(folder / "results.csv", half),
        )
        print(f"stopped half way (SIGTERM): peak RSS {peak:.0f} MB, CPU {cpu:.0f} s")
        peak, cpu = run(["run", "--resume", str(folder), "--quiet", "--fmu-dir", str(args.fmu_dir)])
        print(f"resumed: peak RSS {peak:.0f} MB, CPU {cpu:.0f} s, {sizes(folder, rows)}")


if __name__ == "__main__":
    main()
