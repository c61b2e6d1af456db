"""``auv-cosim sweep`` on a local cluster: a bs-3 grid study equals separate runs, failed
runs are rows, results do not depend on the number of workers, bad studies fail early."""

from __future__ import annotations

import json
import math
import re
import tomllib
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import tomli_w
from repo_paths import ROOT
from sweep_helpers import GRID_STUDY, sweep, table

from cosim.cli import main
from cosim.metrics.manoeuvres import metric_names
from cosim.scenario.design_doubts import DesignWarning
from cosim.scenario.unit_doubts import UnitWarning
from cosim.study.design import random_samples
from cosim.study.spec import load_study

pytestmark = pytest.mark.usefixtures("no_early_cluster")  # refusals wait for no cluster


def separate_run(tmp_path: Path, fmu_dir: Path, v0: float, k0: float) -> dict:
    """bs-3 with these start values through `auv-cosim run`: its summary.json."""
    data = tomllib.loads((ROOT / "cosim/scenarios/bs-3.toml").read_text(encoding="utf-8"))
    data["instances"]["plant"]["start"]["v_0"] = v0
    data["instances"]["controller"]["start"]["k0"] = k0
    scenario = tmp_path / f"bs-3_{v0}_{k0}.toml"
    scenario.write_text(tomli_w.dumps(data), encoding="utf-8")
    out = tmp_path / scenario.stem
    argv = ["run", str(scenario), "--stop-time", "20", "--no-rrd", "--quiet"]
    assert main([*argv, "--out", str(out), "--fmu-dir", str(fmu_dir)]) == 0
    return json.loads((out / "summary.json").read_text(encoding="utf-8"))


@pytest.mark.cluster
@pytest.mark.slow
def test_a_grid_study_equals_eight_separate_runs(tmp_path: Path, fmu_dir: Path) -> None:
    study = tmp_path / "study.toml"
    study.write_text(GRID_STUDY, encoding="utf-8")
    sweep(study, tmp_path / "out", fmu_dir, "--workers", "2")
    rows = table(tmp_path / "out")
    assert len(rows) == 8 and {r["status"] for r in rows} == {"complete"}
    grid = [(v0, k0) for v0 in ("-0.1", "-0.05", "0.05", "0.1") for k0 in ("0.2", "0.5")]
    assert [(r["plant.v_0"], r["controller.k0"]) for r in rows] == grid  # the study's order
    assert [(r["point"], r["sample"]) for r in rows] == [(str(k), "") for k in range(8)]
    for row in rows:
        summary = separate_run(
            tmp_path, fmu_dir, float(row["plant.v_0"]), float(row["controller.k0"])
        )
        expected = {**summary["key_figures"], "time_reached": summary["time_reached"]}
        expected |= {f"final.{k}": v for k, v in summary["final_values"].items()}
        place = ("point", "sample")  # in the study's design
        metrics = {k: v for k, v in row.items() if k not in ("run", "status", "error", *place)}
        metrics = {k: v for k, v in metrics.items() if k not in ("plant.v_0", "controller.k0")}
        assert set(metrics) == set(expected)
        for name, value in expected.items():  # exactly: the text reads back to the double
            assert metrics[name] == ("" if value is None else repr(value)), name
    assert any(r["yaw_settling_time_s"] for r in rows)  # 20 s: the settling time is there


@pytest.mark.cluster
@pytest.mark.slow
def test_runs_parquet_gives_the_units_a_kept_runs_summary_gives(
    tmp_path: Path, fmu_dir: Path
) -> None:
    """runs.csv's header names no unit; runs.parquet does, field by field, and agrees with
    summary.json: ``final.<column>`` has the unit the kept run's summary gives ``<column>``,
    a factor its variable's (``plant.v_0`` in m/s), a key figure the one its name ends in."""
    study = tmp_path / "study.toml"
    study.write_text(
        'scenario = "bs-3"\nstop_time = 0.2\nkeep = "all"\n[grid]\n"plant.v_0" = [-0.1, 0.1]\n',
        encoding="utf-8",
    )
    sweep(study, tmp_path / "out", fmu_dir, "--workers", "2")
    schema = pq.read_schema(tmp_path / "out" / "runs.parquet")
    unit = {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in schema}
    run = table(tmp_path / "out")[0]["run"]
    summary = json.loads((tmp_path / "out" / "runs" / run / "summary.json").read_text())
    finals = {name: unit[f"final.{name}"] for name in summary["final_values"]}
    assert finals == {name: summary["units"][name] for name in summary["final_values"]}
    assert (unit["plant.v_0"], unit["peak_abs_tunnel_force_N"], unit["time_reached"]) == (
        "m/s", "N", "s"
    )  # fmt: skip
    assert unit["wall_clock_s"] == "s" and unit["status"] == ""


@pytest.mark.cluster
@pytest.mark.slow
def test_a_refused_start_value_is_a_failed_row_the_others_complete(
    tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = tmp_path / "variants.toml"
    text = 'scenario = "bs-3"\nstop_time = 1.0\nkeep = "failed"\n[grid]\n'
    # the plant refuses a mass beyond its stroke (no declared range says so)
    grid = '"plant.mass_position_0" = [0.01, 0.5, 0.02]\n'
    study.write_text(text + grid, encoding="utf-8")
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "2")
    rows = {float(r["plant.mass_position_0"]): r for r in table(out)}
    assert [rows[v]["status"] for v in (0.01, 0.02, 0.5)] == ["complete", "complete", "failed"]
    assert "mass_position_0 = 0.5 m: expected |mass_position_0| <=" in rows[0.5]["error"]
    # the study's last lines say which run failed and why (a study said "1 failed" only)
    failed = f"  first failed run {rows[0.5]['run']} (plant.mass_position_0 = 0.5): "
    assert failed + rows[0.5]["error"] in capsys.readouterr().out.splitlines()
    assert rows[0.5]["time_reached"] == "" and rows[0.02]["time_reached"] == "1.0"
    kept = sorted(p.name for p in (out / "runs").iterdir())
    assert kept == [rows[0.5]["run"]]  # keep = "failed": only the failed run's folder
    folder = out / "runs" / rows[0.5]["run"]
    assert rows[0.5]["error"] in (folder / "error.txt").read_text(encoding="utf-8")
    # the kept scenario reproduces the failure with `auv-cosim run`
    argv = ["run", str(folder / "scenario.toml"), "--no-rrd", "--out", str(tmp_path / "again")]
    assert main([*argv, "--fmu-dir", str(fmu_dir), "--quiet"]) == 1
    assert (out / "index.html").is_file() and "Failed runs" in (out / "index.html").read_text()

    # the folder now holds this study: a new one is refused, so is resuming another study
    assert main(["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]) == 1
    study.write_text(text.replace("1.0", "2.0") + grid)
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--resume"]
    assert main(argv) == 1


@pytest.mark.cluster
@pytest.mark.slow
def test_the_table_does_not_depend_on_the_number_of_workers(
    small_study: Path, small_reference: list[dict[str, str]], fmu_dir: Path, tmp_path: Path
) -> None:
    sweep(small_study, tmp_path / "one", fmu_dir, "--workers", "1")
    assert table(tmp_path / "one") == small_reference
    assert (tmp_path / "one" / "figures" / "scatter_matrix.png").is_file()


@pytest.mark.parametrize(
    ("factor", "expected"),
    [
        ('"plant.v0" = [0.1]', "factor 'plant.v0': plant has no parameter or input 'v0'"),
        ('"plant.yaw" = [0.1]', "plant.yaw is a continuous output"),
        ('"plant.v_0" = ["fast"]', "'fast' is not a number (v_0 is Real)"),
        ('"plant.v_0" = [nan]', "nan is not a finite number"),
        # a Real beyond its declared range, in a grid and in a distribution's samples
        ('"controller.k0" = [0.5, -1.0]', "-1.0 is outside [0.0, inf], the range k0 takes"),
        ('[random]\nn = 50\nseed = 1\n"controller.k0" = { normal = [0.5, 0.5] }',
         "factor 'controller.k0': 7 of its 50 samples are outside [0.0, inf], the range k0"),
        # a law wider than a float holds (the width 2e308 overflows): named, no traceback
        ('[random]\nn = 2\nseed = 1\n"plant.v_0" = { uniform = [-1e308, 1e308] }',
         "factor 'plant.v_0': {'uniform': (-1e+308, 1e+308)} gives samples beyond the largest"),
        # an Integer drawn at random: refused for its first sample's type, not its own
        ('[random]\nn = 2\nseed = 1\n"controller.heading_mode" = { uniform = [1, 3] }',
         "factor 'controller.heading_mode': heading_mode is Integer; a random factor draws "
         "real numbers, so it varies a Real variable (vary this one in [grid])"),
    ],
)  # fmt: skip
def test_a_bad_factor_fails_before_any_run_naming_it(
    factor: str, expected: str, tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    study = tmp_path / "bad.toml"
    table = "" if factor.startswith("[random]") else "[grid]\n"
    study.write_text(f'scenario = "bs-3"\n{table}{factor}\n', encoding="utf-8")
    out = tmp_path / "out"
    assert main(["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]) == 1
    assert expected in capsys.readouterr().err
    assert not out.exists()


def test_samples_beside_a_grid_are_counted_once_not_once_per_grid_point(
    tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    """Every grid point runs the same n samples, but a refusal of samples outside a range
    (and the warning of angles beyond a full turn) counted them at every grid point: "14
    of its 100 samples" for a study that draws 50."""
    draws = '[random]\nn = 50\nseed = 1\n"controller.k0" = { normal = [0.5, 0.5] }\n'
    grid = '[grid]\n"plant.v_0" = [-0.1, 0.1]\n'
    study = tmp_path / "bad.toml"
    study.write_text(f'scenario = "bs-3"\n{grid}{draws}', encoding="utf-8")
    out = tmp_path / "out"
    assert main(["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]) == 1
    alone = [s["controller.k0"] for s in random_samples(load_study(study).random)]
    below = sum(k < 0.0 for k in alone)
    assert f"{below} of its 50 samples are outside [0.0, inf]" in capsys.readouterr().err
    turns = draws.replace("controller.k0", "plant.yaw_0").replace("0.5, 0.5", "0.0, 5.0")
    study.write_text(f'scenario = "bs-3"\nstop_time = 0.1\n{grid}{turns}', encoding="utf-8")
    yaws = [abs(s["plant.yaw_0"]) for s in random_samples(load_study(study).random)]
    beyond = sum(y > 2 * math.pi for y in yaws)
    out.mkdir()
    (out / "mine.txt").write_text("not a study\n")  # refused after the samples are checked
    with pytest.warns(UnitWarning, match=f"{beyond} of its 50 samples are more than a full"):
        assert main(["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]) == 1


@pytest.mark.parametrize(
    ("scenario", "factor", "expected"),
    [
        ("depth-steps", '"events.down-to-3m.time" = { normal = [1.0, 2.0] }',
         r"factor 'events.down-to-3m.time': \d+ of its 50 samples are outside \[0.0, inf\], "
         "the range time takes"),
        ("mass-jam", '"faults.jam.start" = { uniform = [-1.0, 3.0] }',
         r"factor 'faults.jam.start': \d+ of its 50 samples are outside \[0.0, inf\], the "
         "range start takes"),
    ],
)  # fmt: skip
def test_samples_of_an_event_or_fault_key_are_checked_before_any_run(
    scenario: str, factor: str, expected: str, tmp_path: Path, fmu_dir: Path, capsys
) -> None:
    """A distribution of an event's time reaching below 0 ran, and its samples there were
    failed rows ("Input should be greater than or equal to 0"), where a start value's
    samples are refused before the first run."""
    study = tmp_path / "bad.toml"
    text = f'scenario = "{scenario}"\n[random]\nn = 50\nseed = 1\n{factor}\n'
    study.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]) == 1
    assert re.search(expected, capsys.readouterr().err)
    assert not out.exists()


def test_unknown_metric_is_named_with_the_metrics_a_run_reports(
    tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    study = tmp_path / "metrics.toml"
    text = 'scenario = "bs-3"\n[grid]\n"plant.v_0" = [0.1]\n[metrics]\ncollect = ["settling"]\n'
    study.write_text(text, encoding="utf-8")
    assert (
        main(["sweep", str(study), "--out", str(tmp_path / "out"), "--fmu-dir", str(fmu_dir)]) == 1
    )
    err = capsys.readouterr().err
    assert "unknown metric 'settling'" in err and "yaw_settling_time_s" in err
    study.write_text(text.replace('"settling"', '"yaw_setling_time_s"'), encoding="utf-8")
    assert (
        main(["sweep", str(study), "--out", str(tmp_path / "out"), "--fmu-dir", str(fmu_dir)]) == 1
    )
    assert "(did you mean 'yaw_settling_time_s'?)" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (["--workers", "0"], "--workers 0: expected at least 1 worker process"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not both"),
        (
            ["--dashboard", "--scheduler", "tcp://127.0.0.1:1"],
            "--dashboard: a --scheduler cluster serves its own dashboard",
        ),
    ],
)
def test_bad_cluster_options_fail_before_anything_is_written(
    options: list[str], expected: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    study = tmp_path / "study.toml"
    study.write_text(GRID_STUDY, encoding="utf-8")
    assert main(["sweep", str(study), "--out", str(tmp_path / "out"), *options]) == 1
    assert expected in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# 2.4.1: older than the bokeh of every Dask pyproject allows (2024.8 needs >= 2.4.2)
@pytest.mark.parametrize("installed", [None, "2.4.1"])
def test_a_dashboard_without_the_bokeh_dask_needs_is_refused_before_the_cluster_starts(
    installed: str | None,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """--dashboard on a machine without bokeh (or with one Dask cannot use) used to run
    the study without a word: no dashboard, no address, no reason."""
    import importlib.metadata

    from distributed.versions import BOKEH_REQUIREMENT

    from cosim.study import fork_server

    real = importlib.metadata.version

    def version(name: str) -> str:
        if name != "bokeh":
            return real(name)
        if installed is None:
            raise importlib.metadata.PackageNotFoundError(name)
        return installed

    monkeypatch.setattr(importlib.metadata, "version", version)
    monkeypatch.setattr(
        fork_server, "start", lambda warm=False: pytest.fail("a fork server started")
    )
    study = tmp_path / "study.toml"
    study.write_text(GRID_STUDY, encoding="utf-8")
    assert main(["sweep", str(study), "--out", str(tmp_path / "out"), "--dashboard"]) == 1
    err = capsys.readouterr().err
    found = "it is not installed" if installed is None else f"not bokeh {installed}"
    needs = f"--dashboard: Dask's dashboard needs {BOKEH_REQUIREMENT} ("  # the installed Dask's
    assert needs in err and found in err, err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "out").exists()


@pytest.mark.cluster
@pytest.mark.slow
def test_a_study_of_a_manoeuvre_collects_its_metrics(tmp_path: Path, fmu_dir: Path) -> None:
    """Regression: a study over turning-circle has the manoeuvre's metrics as columns, each
    run's as its summary.json gives them (tactical diameter: 180 deg after about 16 s)."""
    study = tmp_path / "turns.toml"
    text = 'scenario = "turning-circle"\nstop_time = 20.0\nkeep = "all"\n[grid]\n'
    study.write_text(text + '"plant.mass_position_cmd" = [0.04, 0.06]\n', encoding="utf-8")
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "1")
    rows = {float(r["plant.mass_position_cmd"]): r for r in table(out)}
    for row in rows.values():
        summary = json.loads((out / "runs" / row["run"] / "summary.json").read_text("utf-8"))
        for name in metric_names("turning-circle"):
            value = summary[name]
            assert row[name] == ("" if value is None else repr(value)), name
    # both reach the 180 deg point, each on its own circle; 20 s hold no steady full turn
    diameters = {float(row["tactical_diameter_m"]) for row in rows.values()}
    assert len(diameters) == 2 and min(diameters) > 5.0
    assert rows[0.06]["steady_turning_diameter_m"] == ""


@pytest.mark.cluster
@pytest.mark.slow
def test_a_study_of_fmus_nobody_here_wrote_has_no_empty_auv_columns(
    tmp_path: Path, fmu_dir: Path
) -> None:
    """A study of the Reference Dahlquist FMU: its table holds the factor, the time reached
    and the final value, not the AUV's key figures, which no column of it could give
    (three columns empty in every row before)."""
    dahlquist = ROOT / "tests" / "data" / "reference-fmus" / "Dahlquist.fmu"
    scenario = tmp_path / "dahlquist.toml"
    scenario.write_text(
        f'stop_time = 2.0\n[coupling]\nstep = 0.1\n[instances.d]\nfmu = "{dahlquist}"\n'
    )
    study = tmp_path / "study.toml"
    study.write_text('scenario = "dahlquist.toml"\n[grid]\n"d.k" = [0.5, 1.0, 2.0]\n')
    sweep(study, tmp_path / "out", fmu_dir, "--workers", "1")
    rows = table(tmp_path / "out")
    assert list(rows[0]) == [
        "run",
        "d.k",
        "time_reached",
        "final.d.x",
        "status",
        "error",
        "point",
        "sample",
    ]
    assert [float(row["final.d.x"]) < 1.0 for row in rows] == [True] * 3


@pytest.mark.cluster
@pytest.mark.slow
def test_a_named_value_and_a_number_in_one_grid_run_and_are_tabled_by_name(
    tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A grid of an enumeration's name and a number ("lateral", 2) ended in a pyarrow
    traceback after its runs, and every --resume in the same; ("lateral", 1), one value
    written two ways, ran twice."""
    study = tmp_path / "variants.toml"
    text = 'scenario = "bs-3"\nstop_time = 0.5\n[grid]\n"plant.variant" = ["lateral", {}]\n'
    study.write_text(text.format(1), encoding="utf-8")
    argv = ["sweep", str(study), "--out", str(tmp_path / "twice"), "--fmu-dir", str(fmu_dir)]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "[grid] 'plant.variant': 'lateral' and 1 are one value, 'lateral': list" in err, err
    study.write_text(text.format(2), encoding="utf-8")
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "1")
    rows = table(out)
    assert [r["plant.variant"] for r in rows] == ["lateral", "horizontal"]
    assert {r["status"] for r in rows} == {"complete"}
    assert (out / "runs.parquet").is_file() and (out / "index.html").is_file()


@pytest.mark.cluster
@pytest.mark.slow
def test_a_factor_naming_a_file_is_read_beside_the_study_file_from_any_folder(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A vehicle set named by a factor was looked for in the working directory (another
    one of that name there was used), and the kept scenario.toml named it as written, so
    `auv-cosim run` of it failed from the run's folder."""
    studies, elsewhere = tmp_path / "studies", tmp_path / "elsewhere"
    studies.mkdir(), elsewhere.mkdir()
    vehicle = 'base = "remus100"\nname = "{}"\n[rigid_body]\nm = {}\n'
    (studies / "heavy.toml").write_text(vehicle.format("heavy", 31.0), encoding="utf-8")
    (elsewhere / "heavy.toml").write_text(vehicle.format("decoy", 45.0), encoding="utf-8")
    study = studies / "vehicles.toml"
    study.write_text(
        'scenario = "bs-3"\nstop_time = 0.2\nkeep = "all"\n[grid]\n'
        '"plant.vehicle" = ["remus100", "heavy.toml"]\n',
        encoding="utf-8",
    )
    monkeypatch.chdir(elsewhere)
    out = tmp_path / "out"
    with pytest.warns(DesignWarning, match="heavy.toml"):  # the study says so once, too
        sweep(study, out, fmu_dir, "--workers", "1")
    rows = {r["plant.vehicle"]: r for r in table(out)}
    assert {r["status"] for r in rows.values()} == {"complete"}, rows
    kept = out / "runs" / rows["heavy.toml"]["run"] / "scenario.toml"
    named = tomllib.loads(kept.read_text(encoding="utf-8"))["instances"]["plant"]["start"]
    assert named["vehicle"] == str(studies / "heavy.toml")
    monkeypatch.chdir(kept.parent)
    argv = ["run", str(kept), "--no-rrd", "--quiet", "--out", str(tmp_path / "again")]
    # the heavier plant beside an autopilot designed for remus100: said, and run all the same
    with pytest.warns(DesignWarning, match="heavy.toml"):
        assert main([*argv, "--fmu-dir", str(fmu_dir)]) == 0


@pytest.mark.cluster
@pytest.mark.slow
def test_a_local_cluster_has_no_more_workers_than_runs(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--workers 8 --oversubscribe on a study of 2 runs started 8 worker processes (100
    took 42 s on 2 cores before the first run)."""
    from cosim.study import execution

    started = []
    early = execution.early_client

    def counted(workers: int, *args, **kwargs):
        started.append(workers)
        return early(workers, *args, **kwargs)

    monkeypatch.setattr(execution, "early_client", counted)
    study = tmp_path / "two.toml"
    study.write_text(
        'scenario = "bs-3"\nstop_time = 0.2\n[grid]\n"plant.v_0" = [0.0, 0.1]\n', encoding="utf-8"
    )
    sweep(study, tmp_path / "out", fmu_dir, "--workers", "8", "--oversubscribe")
    assert started == [2]
    assert len(table(tmp_path / "out")) == 2
