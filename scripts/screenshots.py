"""Regenerate the pictures of what a user sees first into docs/figures/:

* ``user-report-attitude.png`` and ``user-report-lateral.png``: ``auv-cosim report`` of a
  bs-3 run (the transient column, the settling time, the actuator limits; the lateral
  deviation against the distance along the course);
* ``user-study-grid.png``: the README's example study's page figure (its default
  metrics, with units);
* ``user-recording-layout.png``: the recording's default layout in the native Rerun
  viewer, headless (:mod:`cosim.viz.screenshot`; needs a Vulkan driver, e.g. Debian's
  mesa-vulkan-drivers: without one this picture is skipped with the reason).

    python scripts/screenshots.py [--out docs/figures]

Every command runs as a user would run it, from this checkout (``python -m cosim.cli``),
in a temporary folder; the FMUs are built in (or taken from) ./build/fmus.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_user import STUDY  # the README's example study (scripts/ is on the path)

from cosim.viz.screenshot import ScreenshotError, render_screenshots

REPO = Path(__file__).resolve().parents[1]
RECORDING_TIME_S = 6.0  # the time cursor of the recording's picture


def cosim(*args: str) -> None:
    """``auv-cosim ARGS`` from this checkout, in the repository (its build/fmus)."""
    path = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    subprocess.run(
        [sys.executable, "-m", "cosim.cli", *args],
        cwd=REPO, env={**os.environ, "PYTHONPATH": path}, check=True,
    )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "figures")
    out = parser.parse_args().out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="screenshots-") as tmp:
        run, study = Path(tmp) / "bs-3", Path(tmp) / "study"
        cosim("run", "bs-3", "--out", str(run), "--quiet")
        cosim("report", str(run))
        shutil.copyfile(run / "report" / "attitude_actuators.png", out / "user-report-attitude.png")
        shutil.copyfile(run / "report" / "lateral_deviation.png", out / "user-report-lateral.png")
        (Path(tmp) / "study.toml").write_text(STUDY)
        cosim("sweep", str(Path(tmp) / "study.toml"), "--workers", "2", "--out", str(study),
              "--quiet")  # fmt: skip
        shutil.copyfile(study / "figures" / "grid_plant.v_0.png", out / "user-study-grid.png")
        home = Path(tmp) / "home"  # the viewer's settings stay out of $HOME
        env = dict(os.environ, HOME=str(home), XDG_CONFIG_HOME=f"{home}/config",
                   XDG_DATA_HOME=f"{home}/data", XDG_CACHE_HOME=f"{home}/cache")  # fmt: skip
        picture = out / "user-recording-layout.png"
        try:
            render_screenshots(run / "recording.rrd", [(RECORDING_TIME_S, picture)], env=env)
        except ScreenshotError as exc:
            print(f"{picture.name} skipped: {exc}")
    print(f"pictures in {out}")


if __name__ == "__main__":
    main()
