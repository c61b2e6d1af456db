"""Render a run's recording to a PNG with the headless native viewer (docs/recording.png).

    python scripts/render_recording.py runs/bs-3 --time 6 --out docs/recording.png

RUN is a run folder holding recording.rrd (``auv-cosim run bs-3``) or an .rrd file. The
picture is the whole viewer with the recording's default blueprint, 1920x1080, the time
cursor at ``--time`` seconds. Needs a Vulkan driver (Debian: mesa-vulkan-drivers).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from cosim.viz.recording import RECORDING_FILE
from cosim.viz.screenshot import ScreenshotError, render_screenshots


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="run folder or .rrd file")
    parser.add_argument("--time", type=float, required=True, help="time cursor, s")
    parser.add_argument("--out", type=Path, default=Path("docs/recording.png"))
    args = parser.parse_args(argv)
    rrd = args.run / RECORDING_FILE if args.run.is_dir() else args.run
    if not rrd.is_file():
        sys.exit(
            f"render_recording: {rrd}: no recording (expected a run folder holding "
            f"{RECORDING_FILE}, which a run with --no-rrd does not write, or an .rrd file)"
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as home:  # the viewer's settings stay out of $HOME
        env = dict(os.environ, HOME=home, XDG_CONFIG_HOME=f"{home}/config")
        env.update(XDG_DATA_HOME=f"{home}/data", XDG_CACHE_HOME=f"{home}/cache")
        try:
            reports = render_screenshots(rrd, [(args.time, args.out)], env=env)
        except ScreenshotError as exc:  # no viewer, no Vulkan, a recording it cannot load
            sys.exit(f"render_recording: {exc}")
    for report in reports:
        for problem in report.problems:
            print(f"view {report.name!r}: {problem}")
    print(f"{args.out}: {len(reports)} views")


if __name__ == "__main__":
    main()
