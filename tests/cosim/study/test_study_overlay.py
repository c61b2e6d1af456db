"""The study's Rerun overlay: ``overlay = [...]`` in the study file or ``--overlay N``
writes overlay.rrd with the chosen runs' paths and yaw/roll/depth series (read back with
rerun.chunk.RrdReader), from their results.csv (kept, or run again and kept); choices
that cannot be met are refused before the first run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader
from sweep_helpers import sweep, table

from cosim.cli import main
from cosim.study.design import PlannedRun, run_id
from cosim.study.overlay import choose, spread
from cosim.viz.report import load_results

pytestmark = pytest.mark.usefixtures("no_early_cluster")  # refusals wait for no cluster

STUDY = """
scenario = "bs-3"
stop_time = 2.0
overlay = [{entries}]
[grid]
"plant.v_0" = [-0.10, 0.0, 0.10]
"plant.current_east" = [0.0, 0.2]
[metrics]
collect = ["final.plant.north", "final.plant.yaw"]
"""
NAMED = {"plant.v_0": 0.0, "plant.current_east": 0.2}


def recording(path: Path) -> dict[str, dict[str, list]]:
    """Entity path -> component -> the values of every row (static rows first)."""
    found: dict[str, dict[str, list]] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        components = found.setdefault(chunk.entity_path, {})
        for name in batch.schema.names:
            components.setdefault(name, []).extend(batch.column(name).to_pylist())
    return found


def write_study(folder: Path, entries: str) -> Path:
    path = folder / "overlay.toml"
    path.write_text(STUDY.format(entries=entries), encoding="utf-8")
    return path


def runs_in(rrd: dict[str, dict[str, list]]) -> set[str]:
    return {entity.rsplit("/", 1)[1] for entity in rrd if entity.startswith("/world/paths/")}


@pytest.mark.cluster
@pytest.mark.slow
def test_the_overlay_holds_the_chosen_runs(fmu_dir: Path, tmp_path: Path) -> None:
    named = run_id(NAMED)
    study = write_study(tmp_path, f'"best:final.plant.north", "worst:final.plant.yaw", "{named}"')
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "2")
    rows = table(out)
    best = min(rows, key=lambda row: float(row["final.plant.north"]))["run"]
    worst = max(rows, key=lambda row: float(row["final.plant.yaw"]))["run"]
    chosen = {best, worst, named}
    rrd = recording(out / "overlay.rrd")
    assert runs_in(rrd) == chosen
    by_run = {row["run"]: row for row in rows}
    for run in chosen:
        label = rrd[f"/world/paths/{run}"]["LineStrips3D:labels"][0][0]
        factors = ", ".join(f"{name} = {float(by_run[run][name]):.6g} m/s" for name in NAMED)
        assert label == f"{run}: {factors}"
        # the chosen runs were kept (run again: the table's runs kept nothing) ...
        results = load_results(out / "runs" / run)
        summary = json.loads((out / "runs" / run / "summary.json").read_text())
        # ... and the re-run is the run of the table's row
        assert repr(summary["final_values"]["plant.north"]) == by_run[run]["final.plant.north"]
        for root, column, scale in (
            ("yaw_deg", "plant.yaw", np.degrees(1.0)),
            ("roll_deg", "plant.roll", np.degrees(1.0)),
            ("depth_m", "plant.down", 1.0),
        ):
            entity = rrd[f"/{root}/{run}"]
            assert entity["SeriesLines:names"] == [[label]]
            values = np.concatenate([v for v in entity["Scalars:scalars"] if v is not None])
            np.testing.assert_array_equal(values, results[column] * scale)
        strip = np.asarray(rrd[f"/world/paths/{run}"]["LineStrips3D:strips"][0][0])
        path = np.column_stack([results[f"plant.{axis}"] for axis in ("north", "east", "down")])
        np.testing.assert_allclose(strip, path, rtol=1e-6)  # stored as float32
    assert sorted(p.name for p in (out / "runs").iterdir()) == sorted(chosen)
    notes = rrd["/study"]["TextDocument:text"][0][0]
    assert f"| `{best}` | best:final.plant.north" in notes
    assert (
        f"| `{named}` | {named} | plant.v_0 = 0 m/s, plant.current_east = 0.2 m/s | complete |"
        in notes
    )
    page = (out / "index.html").read_text()  # the page says where the overlay is
    assert f"overlay.rrd: the chosen runs in one Rerun recording; auv-cosim view {out}" in page

    # --overlay N on the finished study: N runs spread over its order, first and last
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--quiet"]
    assert main([*argv, "--workers", "2", "--resume", "--overlay", "2"]) == 0
    first, last = (
        run_id({"plant.v_0": -0.10, "plant.current_east": 0.0}),
        run_id({"plant.v_0": 0.10, "plant.current_east": 0.2}),
    )
    assert runs_in(recording(out / "overlay.rrd")) == {first, last}
    assert table(out) == rows
    assert not list(out.glob("*.tmp"))


@pytest.mark.cluster
@pytest.mark.slow
def test_the_overlay_s_runs_again_show_progress_and_are_counted(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Resuming a finished study with --overlay ran the chosen runs again for seconds with
    no progress bar, then said "0 run now": nothing told how long, or that anything ran."""
    import cosim.cli

    study = tmp_path / "plain.toml"
    study.write_text(STUDY.replace("overlay = [{entries}]\n", ""), encoding="utf-8")
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "2")
    capsys.readouterr()
    monkeypatch.setattr(cosim.cli, "_progress_bar", lambda args: True)  # as on a terminal
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--resume"]
    assert main([*argv, "--workers", "2", "--overlay", "2"]) == 0
    said = capsys.readouterr()
    bars = [line for line in said.err.replace("\r", "\n").splitlines() if line.strip()]
    assert any(line.startswith("overlay") and "2/2" in line for line in bars), said.err
    assert "(6 already in the table, 0 run now, 2 run again for the overlay)" in said.out


@pytest.mark.cluster
@pytest.mark.slow
def test_a_study_resumed_without_overlay_still_names_the_overlay_it_holds(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """Resuming a study without --overlay rewrote its page without the overlay's row, while
    overlay.rrd stayed in the folder (and `auv-cosim view` of the folder opened it)."""
    study = tmp_path / "plain.toml"
    study.write_text(STUDY.replace("overlay = [{entries}]\n", ""), encoding="utf-8")
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "2", "--overlay", "1")
    assert "overlay.rrd" in (out / "index.html").read_text(encoding="utf-8")
    sweep(study, out, fmu_dir, "--resume")
    assert (out / "overlay.rrd").is_file()
    assert "overlay.rrd" in (out / "index.html").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("entries", "option", "message"),
    [
        ('"best:wall_clock"', [], "overlay entry 'best:wall_clock': 'wall_clock' is not a"),
        ('"0123456789abcdef"', [], "overlay entry '0123456789abcdef': no run of this study"),
        ('"fastest"', [], "'fastest': expected a run id (16 hex digits), 'best:<metric>'"),
        ('"all"', ["--overlay", "21"], "--overlay 21: expected a number of runs from 1 to 20"),
        ('"all"', ["--overlay", "0"], "--overlay 0: expected a number of runs from 1 to 20"),
    ],
)
def test_an_overlay_that_cannot_be_drawn_is_refused_before_any_run(
    entries: str,
    option: list[str],
    message: str,
    fmu_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
) -> None:
    study = write_study(tmp_path, entries)
    argv = ["sweep", str(study), "--out", str(tmp_path / "out"), "--fmu-dir", str(fmu_dir)]
    assert main([*argv, "--workers", "1", *option]) == 1
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_all_is_capped(fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    study = tmp_path / "big.toml"
    values = ", ".join(str(k / 100) for k in range(21))
    study.write_text(
        f'scenario = "bs-3"\noverlay = ["all"]\n[grid]\n"plant.v_0" = [{values}]\n',
        encoding="utf-8",
    )
    argv = ["sweep", str(study), "--out", str(tmp_path / "out"), "--fmu-dir", str(fmu_dir)]
    assert main([*argv, "--workers", "1"]) == 1
    assert "up to 21 runs, more than the cap of 20" in capsys.readouterr().err


def planned(n: int) -> list[PlannedRun]:
    return [PlannedRun(run_id({"plant.v_0": k / 10}), {"plant.v_0": k / 10}) for k in range(n)]


@pytest.mark.parametrize(("total", "n", "picked"), [(9, 3, [0, 4, 8]), (5, 1, [0]), (2, 5, [0, 1])])
def test_overlay_n_spreads_over_the_study(total: int, n: int, picked: list[int]) -> None:
    runs = planned(total)
    assert spread(runs, n) == [runs[i].id for i in picked]


def test_best_and_worst_skip_failed_runs_and_runs_without_a_value() -> None:
    runs = planned(4)
    values = [None, 2.0, -1.0, -9.0]  # the last run failed: its value is not looked at
    rows = {
        run.id: {"status": "failed" if k == 3 else "complete", "m": values[k]}
        for k, run in enumerate(runs)
    }
    chosen, empty = choose(["best:m", "worst:m", runs[0].id], runs, rows)
    assert chosen == {runs[2].id: ["best:m"], runs[1].id: ["worst:m"], runs[0].id: [runs[0].id]}
    assert empty == []
    nothing = {run.id: {"status": "failed", "m": None} for run in runs}
    assert choose(["best:m"], runs, nothing) == ({}, ["best:m"])


def test_a_mistyped_overlay_metric_gets_a_guess() -> None:
    """'best:yaw_setling_time_s' was refused with the list of 39 collected metrics and no
    word of the one meant."""
    from cosim.study.overlay import check_choice
    from cosim.study.spec import StudyError

    runs = [PlannedRun(run_id({"plant.v_0": 0.1}), {"plant.v_0": 0.1})]
    with pytest.raises(StudyError, match=r"\(did you mean 'yaw_settling_time_s'\?\)"):
        check_choice(["best:yaw_setling_time_s"], runs, ["yaw_settling_time_s", "time_reached"])


def test_a_run_s_label_gives_each_factor_value_with_its_unit_an_angle_in_degrees_too() -> None:
    """The overlay's plots show yaw and roll in degrees: a legend saying ``plant.yaw_0 =
    0.523599`` (rad, no unit) beside a yaw plot starting at 30 read as the wrong number."""
    from cosim.study.overlay import label

    run = PlannedRun("r1", {"plant.yaw_0": 0.5235987755982988, "plant.v_0": -0.1, "x.k": 2})
    unit_of = {"plant.yaw_0": "rad", "plant.v_0": "m/s", "x.k": "1"}
    assert (
        label(run, unit_of)
        == "r1: plant.yaw_0 = 0.523599 rad (30 deg), plant.v_0 = -0.1 m/s, x.k = 2"
    )
