"""What a user waits for: the README's commands timed end to end, from the command to the
prompt, cold and warm, with the machine's load beside every figure.

* ``auv-cosim run bs-3``: the first run in a fresh folder (the FMUs are built, numba
  compiles the plant) and the second; each run's summary.json splits its start-up from
  its stepping loop, printed beside the total.
* the README's example study (Studies: 8 runs of bs-3, 20 s, ``auv-cosim sweep study.toml
  --workers 2``), cold (fresh FMUs and compiled-code cache) and warm: everything included,
  the imports, the cluster's start-up, each worker's first run and the page.

Cold means a fresh FMU folder and a fresh numba cache (``NUMBA_CACHE_DIR`` in a temporary
folder: the user's cache is left alone). Each command runs in a fresh process, in its own
process group, ended with it if the script is interrupted.

    python scripts/bench_user.py [--repeat 3] [--workers 2]

The machine's other load changes every absolute figure: compare the figures only with
the load average printed beside them (``os.getloadavg``: 1-minute average of runnable
processes; a 2-core machine is busy at 2).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_timing import load

REPO = Path(__file__).resolve().parents[1]
HEREDOC = "cat > study.toml <<'END'\n"


def example_study() -> str:
    """The example study of docs/studies.md (the file its first command writes), the one
    the README points to: measured as it is written there."""
    text = (REPO / "docs" / "studies.md").read_text(encoding="utf-8")
    start = text.index(HEREDOC) + len(HEREDOC)
    return text[start : text.index("\nEND\n", start) + 1]


STUDY = example_study()


def timed(args: list[str], cwd: Path, env: dict[str, str]) -> float:
    """Run ``auv-cosim ARGS`` in ``cwd``; the wall time from start to exit, s. Raises
    SystemExit with the command's stderr if it fails."""
    command = [sys.executable, "-m", "cosim.cli", *args]
    started = time.perf_counter()
    process = subprocess.Popen(
        command, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, start_new_session=True,
    )  # fmt: skip
    try:
        _, err = process.communicate(timeout=900)
    except BaseException:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        raise
    elapsed = time.perf_counter() - started
    if process.returncode != 0:
        raise SystemExit(f"auv-cosim {' '.join(args)} failed ({process.returncode}): {err}")
    return elapsed


def run_line(label: str, total: float, summary: Path) -> str:
    data = json.loads(summary.read_text())
    return (
        f"{label:<34} {total:6.2f} s  (start-up {data['startup_total_s']:.2f} s, stepping "
        f"loop {data['wall_clock_s']:.2f} s = {data['real_time_factor']:.1f}x real time)  "
        f"load {load()}"
    )


def bench(repeat: int, workers: int) -> None:
    with tempfile.TemporaryDirectory(prefix="bench-user-") as tmp:
        folder = Path(tmp)
        env = {
            **os.environ,
            "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
            "NUMBA_CACHE_DIR": str(folder / "numba"),
        }
        (folder / "study.toml").write_text(STUDY)
        print(f"machine: {os.cpu_count()} cores; load {load()} at the start")
        print("auv-cosim run bs-3 (recording on, as the README's first command):")
        total = timed(["run", "bs-3"], folder, env)
        print(
            run_line("  first (FMU build + compilation)", total, folder / "runs/bs-3/summary.json")
        )
        for i in range(repeat):
            total = timed(["run", "bs-3", "--overwrite"], folder, env)
            print(run_line(f"  again ({i + 1})", total, folder / "runs/bs-3/summary.json"))
        sweep = ["sweep", "study.toml", "--workers", str(workers), "--quiet"]
        print(f"README study, 8 runs of 20 s, --workers {workers}, command to prompt:")
        env["NUMBA_CACHE_DIR"] = str(folder / "numba-study")  # cold: compiled again
        total = timed([*sweep, "--out", "studies/cold", "--fmu-dir", "fmus-study"], folder, env)
        print(f"  {'cold (FMU build + compilation)':<32} {total:6.2f} s  load {load()}")
        for i in range(repeat):
            total = timed(
                [*sweep, "--out", f"studies/warm-{i}", "--fmu-dir", "fmus-study"], folder, env
            )
            print(f"  {f'warm ({i + 1})':<32} {total:6.2f} s  load {load()}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=2, help="warm repetitions [2]")
    parser.add_argument("--workers", type=int, default=2, help="study workers [2]")
    args = parser.parse_args()
    bench(args.repeat, args.workers)


if __name__ == "__main__":
    main()
