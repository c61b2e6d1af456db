"""A run's start-up (scenario, outputs, loading and initialising the FMUs) is timed apart
from its stepping loop, in summary.json and the report's last line; the progress bar says
what the run does before it steps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scenario_factory import loop_toml

from cosim.outputs.sinks import ProgressSink
from cosim.runner import report, run_scenario
from cosim.scenario.spec import scenario_from_toml

PHASES = ["prepare", "outputs", "load_fmus", "initialise"]


def test_summary_separates_start_up_from_the_loop(test_fmu_dir: Path, tmp_path: Path) -> None:
    scenario = scenario_from_toml(loop_toml(), base_dir=test_fmu_dir)
    outcome = run_scenario(scenario, tmp_path / "run", no_rrd=True)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert list(summary["startup_s"]) == PHASES
    assert all(v >= 0.0 for v in summary["startup_s"].values())
    assert summary["startup_total_s"] == pytest.approx(sum(summary["startup_s"].values()))
    assert summary["wall_clock_s"] == outcome.result.wall_clock_s
    assert summary["real_time_factor"] == pytest.approx(
        summary["time_reached"] / summary["wall_clock_s"]
    )
    last = report(outcome).splitlines()[-1]
    assert "start-up" in last and "loading FMUs" in last and "initialising" in last
    assert last.rstrip().endswith("x real time)") and "stepping loop" in last


def test_progress_bar_says_what_it_does_before_stepping(capsys: pytest.CaptureFixture) -> None:
    bar = ProgressSink(None, "bs-3")
    bar.phase("building FMUs (AuvPlant)")
    bar.phase("initialising")
    bar.total_rows = 3
    bar.add_rows(np.zeros(3), np.zeros((3, 1)))
    bar.close()
    err = capsys.readouterr().err
    assert "bs-3: building FMUs (AuvPlant)" in err
    assert err.index("building FMUs") < err.index("bs-3: initialising") < err.index("/3 ")


def test_the_bar_names_only_the_fmus_the_scenario_builds(tmp_path: Path) -> None:
    from cosim.runner import _fmus_to_build

    assert sorted(_fmus_to_build("bs-3", tmp_path)) == ["AuvAutopilot", "AuvPlant"]
    assert "AuvGuidance" in _fmus_to_build("survey", tmp_path)
    assert _fmus_to_build(tmp_path / "missing.toml", tmp_path) == []


def test_an_adaptive_run_s_bar_counts_simulated_time_to_its_stop_time(
    test_fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """The bar's total was the fixed step's count of rows (11 for 1 s at 0.1 s) while an
    adaptive run counted its own steps against it, thousands at a tolerance of 1e-6: past
    its total the bar became a bare count of steps, with no share done and no time left,
    for the rest of the run. Now an adaptive run's bar counts simulated seconds (s) up to
    its stop time."""
    import re

    text = loop_toml(algorithm="adaptive").replace("[coupling]", "[coupling]\ntolerance = 1e-6")
    scenario = scenario_from_toml(text, base_dir=test_fmu_dir)
    outcome = run_scenario(scenario, tmp_path / "run", no_rrd=True, progress=True)
    assert outcome.result.rows > 2 * scenario.n_steps  # more steps than the fixed step's
    err = capsys.readouterr().err
    counts = [(float(a), float(b)) for a, b in re.findall(r"\| *([0-9.]+)/([0-9.]+) \[", err)]
    assert counts, f"no progress shown: {err!r}"
    assert all(total == scenario.stop_time and done <= total for done, total in counts), counts
    assert "step/s" not in err  # no bare count of steps


def test_the_bar_fits_a_terminal_narrowed_while_it_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """The bars took the terminal's width once, as each began: a terminal narrowed from
    100 to 40 columns mid-run (a window resized, a tmux pane split) had each redraw wrap
    onto a new line, a bar printed again and again down the screen. Each redraw now fits
    the width the terminal has then (the first pads over the wider line before it)."""
    import fcntl
    import os
    import pty
    import select
    import struct
    import sys
    import termios
    import time

    parent, child = pty.openpty()

    def resize(columns: int) -> None:
        fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 24, columns, 0, 0))

    def drawn() -> list[str]:
        """What the bar drew since the last call, redraw by redraw."""
        shown = b""
        while select.select([parent], [], [], 0.5)[0]:
            shown += os.read(parent, 65536)
        return shown.decode().split("\r")

    resize(100)
    monkeypatch.delenv("COLUMNS", raising=False)
    try:
        with os.fdopen(os.dup(child), "w", encoding="utf-8") as terminal:
            monkeypatch.setattr(sys, "stderr", terminal)
            bar = ProgressSink(None, "a-scenario-with-a-long-name")
            bar.phase("loading FMUs")
            bar.total_rows = 1000
            for _ in range(2):
                time.sleep(0.15)  # past tqdm's least interval between redraws (0.1 s)
                bar.add_rows(np.zeros(10), np.zeros((10, 1)))
            terminal.flush()
            wide = drawn()
            resize(40)
            for _ in range(3):
                time.sleep(0.15)
                bar.add_rows(np.zeros(100), np.zeros((100, 1)))
            bar.close()
            terminal.flush()
            narrowed = drawn()
    finally:
        os.close(parent)
        os.close(child)
    assert any(len(r) > 40 and "/1000" in r for r in wide), wide
    bars = [r for r in narrowed if "%|" in r]
    assert len(bars) >= 2, narrowed
    # the first redraw after the change pads with spaces over the wider line before it
    assert all(len(r.rstrip()) <= 40 for r in bars), bars
    assert all(len(r) <= 40 for r in bars[1:]), bars


def test_a_phase_after_the_steps_replaces_the_bar_without_escapes(
    capsys: pytest.CaptureFixture,
) -> None:
    """``run --check-step``: "checking the step" after the steps opened a second bar below
    the step bar, left at 0%, with cursor-up escapes (``ESC [ A``) that a ``TERM=dumb``
    terminal or a CI log shows as text. The step bar ends as the phase begins."""
    bar = ProgressSink(None, "bs-3")
    bar.phase("initialising")
    bar.total_rows = 3
    bar.add_rows(np.zeros(3), np.zeros((3, 1)))
    bar.phase("checking the step (h / 2, h / 4)")
    bar.close()
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\n" not in err, repr(err)
    assert err.index("/3 ") < err.index("bs-3: checking the step"), repr(err)
