"""``auv-cosim report RUN_DIR``: figures and index page from a run folder.

The run folders here are written from the in-process plant model (open loop) in the
documented results.csv / summary.json format, so each figure's data is known.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from chromium import CHROMIUM, overflow
from page_structure import problems, read_page
from process_group import run_in_group
from read_only import read_only_prefix, writable_again
from report_figures import kept_figures

import cosim
from cosim.cli import main
from cosim.errors import CosimError
from cosim.viz.report import index_page, write_report
from plant_fmu.model.dynamics import STATE_NAMES, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import simulate

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _write_run(
    run_dir: Path,
    variant: Variant,
    x0: dict[str, float],
    controller: dict[str, float],
    duration: float = 20.0,
    summary: dict | None = None,
) -> Path:
    """An open-loop run of the plant written as `auv-cosim run` would: plant.* columns
    from the model, controller.* columns held constant (they are the plant's inputs)."""
    model = PlantModel(load_vehicle("remus100"), variant=variant)
    setpoints = ("yaw_setpoint", "depth_setpoint")
    inputs = {"thrust": 9.0, **{k: v for k, v in controller.items() if k not in setpoints}}
    times, states = simulate(model, state_vector(x0), input_vector(inputs), duration, 0.05)
    columns = (
        ["time"] + [f"plant.{n}" for n in STATE_NAMES] + [f"controller.{n}" for n in controller]
    )
    table = np.column_stack([times, states, *[np.full_like(times, v) for v in controller.values()]])
    run_dir.mkdir(parents=True)
    lines = [",".join(columns)] + [",".join(map(repr, row)) for row in table.tolist()]
    (run_dir / "results.csv").write_text("\n".join(lines) + "\n")
    if summary is not None:
        (run_dir / "summary.json").write_text(json.dumps(summary))
    return run_dir


@pytest.fixture(scope="module")
def lateral_run(tmp_path_factory) -> Path:
    """Open-loop lateral motion from v0 = -0.1 (bs-3's initial state, no controller)."""
    return _write_run(
        tmp_path_factory.mktemp("runs") / "open-loop",
        Variant.LATERAL,
        {"u": 1.5, "v": -0.1},
        {"tunnel_force": 0.0, "mass_position_cmd": 0.02, "yaw_setpoint": 0.0},
        summary={
            "scenario": "open-loop",
            "stop_time": 20.0,
            "step": 0.05,
            "complete": True,
            "error": None,
            "wall_clock_s": 0.5,
            "key_figures": {"yaw_settling_time_s": None, "peak_abs_mass_position_m": 0.02},
        },
    )


def _assert_png(path: Path) -> None:
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert len(data) > 10_000  # axes, ticks and curves, not an empty canvas


@pytest.mark.slow
def test_lateral_run_gets_velocity_attitude_and_trajectory_figures(lateral_run):
    index = write_report(lateral_run)
    assert index == lateral_run / "report" / "index.html"
    figures = sorted(p.name for p in index.parent.glob("*.png"))
    # No depth loop: no fins, no depth setpoint, depth constant in the lateral variant.
    assert figures == [
        "attitude_actuators.png",
        "lateral_deviation.png",
        "trajectory.png",
        "velocities.png",
    ]
    for name in figures:
        _assert_png(index.parent / name)
    page = index.read_text()
    for name in figures:
        assert f'src="{name}"' in page
    assert "open-loop" in page and "peak |mass position| (m)" in page


@pytest.mark.slow
def test_depth_loop_gets_its_figure_and_a_3d_trajectory(tmp_path):
    """Full 6-DOF from the surface with the fins deflected: the depth changes."""
    run = _write_run(
        tmp_path / "dive",
        Variant.FULL,
        {"u": 1.5},
        {"fin_angle": 0.1, "depth_setpoint": 1.0},
        duration=10.0,
    )
    index = write_report(run)
    _assert_png(index.parent / "depth.png")
    _assert_png(index.parent / "trajectory.png")
    page = index.read_text()
    assert 'src="depth.png"' in page
    assert "no summary.json" in page  # the report goes on without it, and says so
    stamp = re.search(r'<p class="stamp">(.*?)</p>', page).group(1)
    assert "None" not in stamp  # what it does not know it says so, not as Python's None
    assert "the run in dive (status unknown: no summary.json" in stamp


def test_missing_columns_leave_their_panels_and_figures_out(tmp_path):
    run = tmp_path / "sparse"
    run.mkdir()
    t = np.arange(0.0, 2.0, 0.1)
    rows = "\n".join(f"{a!r},1.5" for a in t.tolist())
    (run / "results.csv").write_text("time,plant.u\n" + rows + "\n")
    index = write_report(run)
    assert sorted(p.name for p in index.parent.glob("*.png")) == ["velocities.png"]


@pytest.mark.parametrize(
    ("key", "odd"),
    [
        ("events", [{"name": "turn"}]),
        ("events", [{"name": "turn", "time": "soon"}]),
        ("events", 5),
        ("faults", [{"name": "jam", "kind": "stuck", "start": None}]),
        ("faults", "x"),
        ("key_figures", [1]),
        ("key_figures", {"yaw_settling_time_s": "late"}),
        ("manoeuvre", [1]),
    ],
    ids=[
        "event-no-time",
        "event-time-text",
        "events-number",
        "fault-no-start",
        "faults-text",
        "key-figures-list",
        "settling-text",
        "manoeuvre-list",
    ],
)
def test_a_summary_entry_of_another_shape_is_named_and_the_report_goes_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str, odd: object
) -> None:
    """summary.json is a file other tools write and users edit: an event without a time,
    a fault without a start, key figures that are no table or a manoeuvre that is no name
    ended the report in a traceback (KeyError: 'time'), where a summary.json that does not
    read at all lets the report go on and says so. The entry is left out and the page names it."""
    run = tmp_path / "odd"
    run.mkdir()
    t = np.arange(0.0, 2.0, 0.1)
    rows = "\n".join(f"{a!r},1.5" for a in t.tolist())
    (run / "results.csv").write_text("time,plant.u\n" + rows + "\n")
    (run / "summary.json").write_text(json.dumps({"scenario": "odd", key: odd}))
    assert main(["report", str(run)]) == 0, capsys.readouterr().err
    page = (run / "report" / "index.html").read_text()
    assert f"summary.json: {key}" in page and "left out" in page
    assert (run / "report" / "velocities.png").is_file()


@pytest.mark.slow
def test_incomplete_run_is_flagged_on_the_page(tmp_path):
    run = _write_run(
        tmp_path / "broken",
        Variant.HORIZONTAL,
        {"u": 1.5},
        {},
        duration=2.0,
        summary={"scenario": "broken", "complete": False, "error": "plant: NaN at t = 2 s"},
    )
    page = write_report(run).read_text()
    assert "did not complete" in page and "plant: NaN at t = 2 s" in page


@pytest.mark.parametrize("value", ["inf", "-inf", "nan"])
def test_a_partial_run_ending_on_a_non_finite_value_is_reported(tmp_path, value):
    """Regression: `report` on a partial run with inf at t = 0 ended in a ValueError."""
    run = tmp_path / "partial"
    run.mkdir()
    (run / "results.csv").write_text(
        "time,plant.yaw,controller.yaw_setpoint,plant.mass_position,controller.mass_position_cmd\n"
        f"0.0,0.1,0.0,{value},0.01\n"
    )
    (run / "summary.json").write_text(
        json.dumps({"scenario": "partial", "status": "incomplete", "complete": False,
                    "error": f"non-finite value at t = 0 s: plant.mass_position = {value}"})
    )  # fmt: skip
    page = write_report(run).read_text()
    assert "did not complete" in page and "non-finite value at t = 0 s" in page
    assert (run / "report" / "attitude_actuators.png").read_bytes().startswith(PNG_SIGNATURE)


@pytest.mark.slow
def test_a_run_still_being_written_is_reported(tmp_path):
    """A killed (or running) run: summary.json says running, the last row is unfinished."""
    summary = {"scenario": "killed", "status": "running", "complete": False}
    run = _write_run(tmp_path / "killed", Variant.HORIZONTAL, {"u": 1.5}, {}, 2.0, summary)
    with (run / "results.csv").open("a") as f:
        f.write("2.05,1.5,0.0")  # torn: no newline
    page = write_report(run).read_text()
    assert "still running (or its process was killed)" in page


def test_folder_without_results_is_a_clear_error(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    with pytest.raises(CosimError, match=r"no results\.csv in .*empty"):
        write_report(tmp_path / "empty")
    assert main(["report", str(tmp_path / "missing")]) == 1
    err = capsys.readouterr().err
    assert "missing does not exist" in err and len(err.strip().splitlines()) == 1


def test_a_study_folder_is_refused_saying_where_its_page_and_runs_are(tmp_path, capsys):
    """``report STUDY`` said "no results.csv ... expected the output folder of `auv-cosim
    run`", as of any folder."""
    study = tmp_path / "study"
    study.mkdir()
    (study / "study.json").write_text("{}")
    for kept in (False, True):  # its runs' folders are kept for an overlay
        if kept:
            (study / "runs").mkdir()
        assert main(["report", str(study)]) == 1
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "is a study folder" in err, err
        assert str(study / "index.html") in err
        assert (str(study / "runs" / "RUN_ID") in err) is kept


def test_results_without_rows_or_time_are_refused(tmp_path):
    header_only = tmp_path / "header"
    header_only.mkdir()
    (header_only / "results.csv").write_text("time,plant.u\n")
    with pytest.raises(CosimError, match="holds no rows"):
        write_report(header_only)
    no_time = tmp_path / "no-time"
    no_time.mkdir()
    (no_time / "results.csv").write_text("plant.u,plant.v\n1.5,0.0\n")
    with pytest.raises(CosimError, match="expected 'time'"):
        write_report(no_time)


def test_results_with_nothing_the_report_draws_are_warned_of(tmp_path):
    """A results.csv recording only columns no figure draws got a report page with no
    figure and no word of why."""
    (tmp_path / "results.csv").write_text("time,other.foo\n0,1\n1,2\n")
    with pytest.warns(RuntimeWarning, match=r"results\.csv holds none of the columns the rep"):
        page = write_report(tmp_path)
    assert "<img" not in page.read_text()


@pytest.mark.slow
def test_a_report_of_two_vehicles_draws_each(tmp_path):
    """Two vehicles (plants plant_a and plant_b): the report drew neither, warning that
    it draws the instances named plant and controller. Each now gets its own figures,
    their files and titles naming its plant, its settling time marked from its own key
    figure."""
    (tmp_path / "results.csv").write_text(
        "time,plant_a.yaw,plant_a.north,plant_a.east,plant_b.yaw,plant_b.north,plant_b.east\n"
        "0,0,0,0,0.2,0,5\n1,0.1,1.5,0,0.2,1.5,5\n2,0.1,3,0.1,0.2,3,5\n",
        encoding="utf-8",
    )
    fmus = {name: {"model": "AuvPlant"} for name in ("plant_a", "plant_b")}
    figures = {"plant_a.yaw_settling_time_s": 0.5, "plant_b.yaw_settling_time_s": None}
    summary = {"fmus": fmus, "key_figures": figures, "scenario": "two", "complete": True}
    (tmp_path / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        page = write_report(tmp_path).read_text(encoding="utf-8")
    made = sorted(p.name for p in (tmp_path / "report").glob("*.png"))
    assert set(made) == {
        f"{name}_{plant}.png"
        for name in ("attitude_actuators", "lateral_deviation", "trajectory")
        for plant in ("plant_a", "plant_b")
    }, made
    assert "<h2>Trajectory (plant_b)</h2>" in page, page
    assert "<h2>Roll and yaw, moving mass and tunnel thruster (plant_a)</h2>" in page, page
    assert problems(page) == []


@pytest.mark.slow
def test_cli_prints_the_index_path(lateral_run, capsys):
    assert main(["report", str(lateral_run)]) == 0
    assert capsys.readouterr().out.strip() == f"report: {lateral_run / 'report' / 'index.html'}"


BS3_RUN = """
import sys
from pathlib import Path
from cosim.runner import run_scenario

fmu_dir, out = Path(sys.argv[1]), Path(sys.argv[2])
outcome = run_scenario("bs-3", out, stop_time=20.0, no_rrd=True, fmu_dir=fmu_dir)
assert outcome.result.complete, outcome.result.error
"""


@pytest.mark.slow
def test_report_of_a_bs3_run_through_the_master(fmu_paths, run_python, tmp_path):
    """Both FMUs through the master (fresh process: pythonfmu caches modules), then the
    report: every figure written and non-empty, the summary on the page."""
    done = run_python(BS3_RUN, fmu_paths["AuvAutopilot"].parent, tmp_path / "bs-3")
    assert done.returncode == 0, done.stderr
    index = write_report(tmp_path / "bs-3")
    figures = sorted(p.name for p in index.parent.glob("*.png"))
    assert figures == [
        "attitude_actuators.png",
        "lateral_deviation.png",
        "trajectory.png",
        "velocities.png",
    ]
    for name in figures:
        _assert_png(index.parent / name)
    page = index.read_text()
    assert "Run bs-3" in page and "yaw settling time (s)" in page


def test_a_far_reference_curve_does_not_flatten_the_main_one() -> None:
    """An unsaturated servo command of metres beside a mass moving within its 6 cm stroke:
    the axis follows the mass, and the command is labelled as leaving it."""
    from cosim.viz.report import Series, _main_range

    t = np.linspace(0.0, 10.0, 101)
    position = 0.06 * np.sin(t)
    command = np.where(t < 2.0, -3.0, position)
    limits = _main_range([(Series("p"), position), (Series("c", dashed=True), command)])
    assert limits is not None and -0.1 < limits[0] < -0.06 and 0.06 < limits[1] < 0.1
    near = _main_range([(Series("p"), position), (Series("c"), position + 0.01)])
    assert near is None


def _settled_run(run: Path, settling: float, controller_start: str = "") -> Path:
    """A lateral run of 20 s that settles in ``settling`` s, with 5 cm mass stops and an
    8 N thruster limit (and ``controller_start``) in its scenario.toml."""
    run = _write_run(
        run, Variant.LATERAL, {"u": 1.5, "v": -0.1},
        {"tunnel_force": 1.0, "mass_position_cmd": 0.02, "yaw_setpoint": 0.0},
        summary={"key_figures": {"yaw_settling_time_s": settling}},
    )  # fmt: skip
    (run / "scenario.toml").write_text(
        '[instances.plant]\nfmu = "AuvPlant"\n[instances.plant.start]\nmass_stroke = 0.05\n'
        '[instances.controller]\nfmu = "AuvAutopilot"\n'
        f"[instances.controller.start]\ntunnel_force_limit = 8.0\n{controller_start}"
    )
    return run


def test_transient_column_settling_time_and_actuator_limits_are_drawn(
    tmp_path, monkeypatch
) -> None:
    """A run that settles in 2 s of 20: the attitude figure gets a column for the first
    6 s, the settling time is a named marker, the mass stops and the thruster limit (from
    the run's start values) are lines at +-limit on their panels."""
    from cosim.viz import report

    run = _settled_run(tmp_path / "run", 2.0, "fin_angle_limit = 0.4\n")
    assert report.actuator_limits(run) == {
        "plant.mass_position": 0.05,
        "controller.tunnel_force": 8.0,
        "controller.fin_angle": 0.4,
    }
    kept = {}

    def keep(fig, path):  # the figure kept to look at, an empty file for the report to move
        kept[path.name] = fig
        path.touch()
        return path

    monkeypatch.setattr(report, "_save", keep)
    write_report(run)
    fig = kept["attitude_actuators.png"]
    panels = [ax for ax in fig.axes if ax.get_ylabel()]
    assert len(panels) == 2 * 5  # roll, yaw, mass, rail speed, F_t: two columns each
    assert panels[1].get_xlim() == pytest.approx((0.0, 6.0))
    legend = [t.get_text() for t in panels[0].get_legend().get_texts()]
    assert "yaw settled (2 s)" in legend
    mass = next(ax for ax in panels if ax.get_ylabel() == "$y_v$ (cm)")
    levels = sorted(line.get_ydata()[0] for line in mass.lines if line.get_linestyle() == ":")
    assert levels == pytest.approx([-5.0, 5.0])  # the 5 cm stops, in cm
    thruster = next(ax for ax in panels if ax.get_ylabel() == "$F_t$ (N)")
    levels = sorted(line.get_ydata()[0] for line in thruster.lines if line.get_linestyle() == ":")
    assert levels == pytest.approx([-8.0, 8.0])
    assert "lateral_deviation.png" in kept


def _sparse_run(run: Path, columns: tuple[str, ...] = ("plant.u",)) -> Path:
    """A run folder whose results.csv holds ``columns`` (1.5 each) for 2 s."""
    run.mkdir(exist_ok=True)
    rows = "\n".join(
        ",".join([repr(t)] + ["1.5"] * len(columns)) for t in np.arange(0, 2, 0.1).tolist()
    )
    (run / "results.csv").write_text(",".join(("time", *columns)) + "\n" + rows + "\n")
    return run


def _a_users_page(run: Path) -> Path:
    (run / "report").mkdir()
    (run / "report" / "index.html").write_text("<p>my notes</p>\n")
    return run / "report" / "index.html"


def _a_users_figure(run: Path) -> Path:
    (run / "report").mkdir()
    (run / "report" / "velocities.png").write_bytes(b"my own figure\n")
    return run / "report" / "velocities.png"


def _a_report_page_edited_since(run: Path) -> Path:
    page = write_report(run)
    page.write_text(page.read_text() + "<p>my notes</p>\n")
    return page


def _a_file_named_report(run: Path) -> Path:
    (run / "report").write_text("my report\n")
    return run / "report"


@pytest.mark.parametrize(
    "make", [_a_users_page, _a_users_figure, _a_report_page_edited_since, _a_file_named_report]
)
def test_a_report_never_writes_over_a_file_no_report_wrote(tmp_path, capsys, make) -> None:
    """`report` overwrote a user's own report/index.html."""
    run = _sparse_run(tmp_path / "run")
    mine = make(run)
    before = mine.read_bytes()
    capsys.readouterr()
    assert main(["report", str(run)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot write the report into" in err, err
    assert mine.read_bytes() == before


def test_a_copied_run_folder_is_reported_again_over_the_copied_report(tmp_path, capsys):
    """A run folder copied with its report (a colleague's run one can only read, copied to
    report it) was refused: "index.html is not a file a report wrote (your own, or changed
    since)", as the copies have other inodes. A copy holding the bytes a report wrote is
    that report's; the copied manifest's other files are replaced and a figure no longer
    drawn is dropped, as in the original folder."""
    run = _sparse_run(tmp_path / "run", ("plant.u", "plant.roll"))
    write_report(run)
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    _sparse_run(copy)  # results.csv of another run: plant.u only
    capsys.readouterr()
    assert main(["report", str(copy)]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in (copy / "report").glob("*.png")) == ["velocities.png"]


def test_a_run_folder_that_cannot_be_written_is_refused_with_a_way_on(tmp_path):
    """A report of a run folder one can only read (a colleague's, an archive's) said only
    "Permission denied; nothing of it is left (no report made)": it says to copy it."""
    run = _sparse_run(tmp_path / "run")
    packages = Path(cosim.__file__).resolve().parents[1]
    path = os.pathsep.join(filter(None, [str(packages), os.environ.get("PYTHONPATH")]))
    command = [sys.executable, "-m", "cosim", "report", str(run)]
    try:
        prefix = read_only_prefix(run)
        done = run_in_group(
            [*prefix, *command], timeout=300, env={**os.environ, "PYTHONPATH": path}
        )
    finally:
        writable_again(run)
    assert done.returncode == 1
    assert done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith(
        f"auv-cosim report: cannot write the report into {run / 'report'}: "
    )
    assert done.stderr.endswith(
        "nothing of it is left (no report made); copy the run folder to a folder you can "
        "write and report the copy\n"
    ), done.stderr
    assert not (run / "report").exists()


def test_a_report_replaces_its_own_files_and_drops_figures_it_no_longer_draws(tmp_path):
    run = _sparse_run(tmp_path / "run", ("plant.u", "plant.roll"))
    index = write_report(run)
    assert (index.parent / "attitude_actuators.png").is_file()
    (index.parent / "notes.txt").write_text("mine\n")
    _sparse_run(run)  # results.csv of another run: plant.u only
    assert write_report(run) == index
    assert sorted(p.name for p in index.parent.glob("*.png")) == ["velocities.png"]
    assert (index.parent / "notes.txt").read_text() == "mine\n"


@pytest.mark.filterwarnings("ignore:.*holds none of the columns the report draws")
def test_a_kept_report_names_its_run_and_is_marked_stale_when_it_is_replaced(
    test_fmu_dir: Path, tmp_path: Path, capsys
) -> None:
    """A report/ kept through --overwrite silently described the earlier run."""
    from scenario_factory import loop_toml

    from cosim.outputs.tail_guard import file_identity

    scenario = tmp_path / "loop.toml"
    scenario.write_text('id = "loop"\n' + loop_toml().replace('"Cosim', f'"{test_fmu_dir}/Cosim'))
    out = tmp_path / "d"
    assert main(["run", str(scenario), "--out", str(out), "--no-rrd"]) == 0
    page = write_report(out)
    digest = file_identity(out / "results.csv")["sha256"]  # type: ignore[index]
    assert f"results.csv SHA-256 <code>{digest[:16]}</code>" in page.read_text()
    assert "Stale" not in page.read_text()
    capsys.readouterr()
    assert main(["run", str(scenario), "--out", str(out), "--no-rrd", "--overwrite"]) == 0
    assert "kept report/ (marked stale: made from the earlier run)" in capsys.readouterr().err
    assert "Stale: this report was made from an earlier run" in page.read_text()
    assert main(["report", str(out)]) == 0  # made again from the run now in the folder
    assert "Stale" not in page.read_text()


def _full_disk_at_the_second_figure(monkeypatch) -> None:
    """Figure.savefig writes half a file, then fails as a full disk does, from the
    second figure on."""
    import errno

    from matplotlib.figure import Figure

    saved = []

    def savefig(self, path, **kwargs):
        if saved:
            Path(path).write_bytes(PNG_SIGNATURE)
            raise OSError(errno.ENOSPC, "No space left on device")
        saved.append(path)
        return real(self, path, **kwargs)

    real = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", savefig)


@pytest.mark.parametrize("earlier", [False, True], ids=["first", "remade"])
def test_a_report_the_disk_had_no_room_for_leaves_nothing_and_can_be_made_later(
    tmp_path, capsys, monkeypatch, earlier
) -> None:
    """A full disk left half a report whose files the next report, with room again,
    refused as "not a file a report wrote"."""
    run = _sparse_run(tmp_path / "run", ("plant.u", "plant.roll"))
    folder = run / "report"
    if earlier:
        write_report(run)
    before = {p.name: p.read_bytes() for p in folder.iterdir()} if earlier else None
    with monkeypatch.context() as patch:
        _full_disk_at_the_second_figure(patch)
        capsys.readouterr()
        assert main(["report", str(run)]) == 1
    err = capsys.readouterr().err
    left = "the earlier report is as it was" if earlier else "no report made"
    assert err == (
        f"auv-cosim report: cannot write the report into {folder}: No space left on device; "
        f"nothing of it is left ({left})\n"
    )
    if earlier:
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    else:
        assert not folder.exists()
    index = write_report(run)  # room again
    assert sorted(p.name for p in folder.glob("*.png")) == ["attitude_actuators.png",
                                                            "velocities.png"]  # fmt: skip
    assert index == folder / "index.html" and not list(folder.glob(".report*"))


def test_a_run_of_one_row_is_drawn_as_points(tmp_path, monkeypatch) -> None:
    """A run that failed at its first step has the t = 0 row only: its report's panels
    were blank (a line through one point draws nothing)."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.csv").write_text("time,plant.u,plant.v\n0.0,1.5,-0.1\n")
    kept = kept_figures(run, monkeypatch)
    lines = [
        line
        for ax in kept["velocities.png"].axes
        for line in ax.lines
        if len(line.get_xdata()) == 1
    ]
    assert lines and all(line.get_marker() == "o" for line in lines)


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_value_beyond_a_float_in_degrees_is_drawn_without_a_warning(tmp_path) -> None:
    """A set-point of 1e308 rad (set live: it declares no range) printed numpy's
    "RuntimeWarning: overflow encountered in multiply" with a source line on stderr."""
    run = tmp_path / "run"
    run.mkdir()
    rows = "".join(f"{t},0.1,1e308\n" for t in (0.0, 0.1, 0.2))
    (run / "results.csv").write_text("time,plant.yaw,controller.yaw_setpoint\n" + rows)
    assert write_report(run).is_file()


def test_key_figures_are_labelled_with_their_unit_in_brackets() -> None:
    """The page's table read "peak abs tunnel force N 9.14" beside "stop time (s) 60": the
    unit a word of the name."""
    from cosim.viz.report import figure_label, index_page

    assert figure_label("peak_abs_tunnel_force_N") == "peak |tunnel force| (N)"
    assert figure_label("yaw_settling_time_s") == "yaw settling time (s)"
    assert figure_label("legs") == "legs"
    assert figure_label("tunnel_force_variation_N_per_s") == "tunnel force variation (N/s)"
    summary = {"scenario": "bs-3", "key_figures": {"peak_abs_mass_position_m": 0.033}}
    page = index_page(Path("runs/bs-3"), summary, None, {})
    assert '<th scope="row">peak |mass position| (m)</th><td>0.033</td>' in page


@pytest.mark.parametrize(
    ("name", "shown"),
    [
        ("run-\udcff", "run-\\xff"),  # Latin-1: the byte 0xff, read as the surrogate U+DCFF
        # Läufe's UTF-8 bytes as Python holds them where it reads names as ASCII
        # (LC_ALL=C, PYTHONUTF8=0): the page said "L\\udcc3\\udca4ufe"
        ("L\udcc3\udca4ufe", "Läufe"),
    ],
)
def test_a_run_folder_named_in_bytes_not_utf8_gets_its_report(
    tmp_path: Path, name: str, shown: str
) -> None:
    """A run folder named in bytes Python did not decode: the page names the folder, and
    writing it failed, "UnicodeEncodeError: 'utf-8' codec can't encode character
    '\\udcff'" (exit 1, no report). The name is written as its bytes read as UTF-8."""
    index = write_report(_sparse_run(tmp_path / name))
    assert f"<code>{tmp_path}/{shown}</code>" in index.read_text(encoding="utf-8")


def _long_run(run: Path, rows: int) -> float:
    """A run folder of ``rows`` rows (a circle at 1.5 m/s, sway noise and one spike);
    returns the spike's sway (m/s)."""
    from cosim.outputs.results import csv_header, csv_lines

    t = np.arange(rows) * 0.01
    v = np.random.default_rng(rows).normal(0.0, 0.01, rows)
    v[rows // 3] = 0.5  # one row out of the noise: a report must still show it
    heading = t / 100.0
    values = np.column_stack([np.full(rows, 1.5), v, 150.0 * np.sin(heading),
                              150.0 * (1.0 - np.cos(heading)), heading])  # fmt: skip
    run.mkdir()
    header = csv_header(["plant.u", "plant.v", "plant.north", "plant.east", "plant.yaw"])
    (run / "results.csv").write_bytes(header.encode() + csv_lines(t, values))
    return 0.5


def test_a_long_run_draws_a_bounded_number_of_points_keeping_every_extreme(
    tmp_path, monkeypatch
) -> None:
    """The report of a 36000 s run drew every one of its 3.6 million rows into each line
    (3.8 GB and minutes for the figures' paths): the points drawn must not grow with the
    run, and what a reader looks for -- a spike, the ends of the track -- must stay."""
    from cosim.viz import report

    monkeypatch.setattr(report, "DRAWN_POINTS_MAX", 2000, raising=False)
    kept: dict[str, object] = {}

    def keep(fig, path):
        kept[path.name] = fig
        path.touch()
        return path

    monkeypatch.setattr(report, "_save", keep)
    drawn = {}
    for rows in (40_000, 160_000):
        spike = _long_run(tmp_path / f"run{rows}", rows)
        kept.clear()
        write_report(tmp_path / f"run{rows}")
        lines = [line for fig in kept.values() for ax in fig.axes for line in ax.lines]
        drawn[rows] = max(len(line.get_xdata()) for line in lines)
        sway = [line for line in kept["velocities.png"].axes[1].lines if line.get_label() != ""]
        assert max(float(np.max(line.get_ydata())) for line in sway) == spike
        track = kept["trajectory.png"].axes[0].lines[0]
        assert track.get_xdata()[-1] == 150.0 * (1.0 - np.cos((rows - 1) * 0.01 / 100.0))
    assert drawn[160_000] <= 2000 and drawn[40_000] <= 2000, f"points in a line: {drawn}"


@pytest.mark.parametrize(("tz", "offset"), [("Europe/Berln", "+0000"), ("JST-9", "+0900")])
def test_a_reports_time_says_its_offset_from_utc_whatever_tz_names(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, tz: str, offset: str
) -> None:
    """The page's "Made <time> <zone>" took the zone's name from TZ: a misspelt
    ``TZ=Europe/Berln`` (which the C library reads as UTC named "Europe") said "Made
    2026-12-06 07:53:12 Europe", an hour off Berlin's time and not saying so. The time
    carries its offset from UTC in digits."""
    import time

    monkeypatch.setenv("TZ", tz)
    time.tzset()
    try:
        page = write_report(_sparse_run(tmp_path / "run")).read_text(encoding="utf-8")
    finally:
        monkeypatch.undo()
        time.tzset()
    made = re.search(r'<p class="stamp">Made (.*?) from ', page)
    assert made is not None, page
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d [+-]\d{4}", made.group(1)), made.group(1)
    assert made.group(1).endswith(offset)


def test_a_report_made_twice_under_source_date_epoch_is_the_same_bytes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A report regenerated for a published page (a documentation build setting
    SOURCE_DATE_EPOCH, as packagers do) changed its page each time: "Made <now>". Under
    SOURCE_DATE_EPOCH the page says that time, in UTC, and two reports are the same."""
    import time

    run = _sparse_run(tmp_path / "run")
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    monkeypatch.setenv("TZ", "JST-9")
    time.tzset()
    try:
        first = write_report(run).read_text(encoding="utf-8")
        time.sleep(1.1)  # another second of the clock
        second = write_report(run).read_text(encoding="utf-8")
    finally:
        monkeypatch.undo()
        time.tzset()
    assert '<p class="stamp">Made 2023-11-14 22:13:20 +0000 from ' in first
    assert first == second


def test_a_source_date_epoch_that_is_no_time_refuses_a_report_not_a_run(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from cosim.errors import CosimError
    from cosim.outputs.report_folder import local_time

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "tomorrow")
    with pytest.raises(CosimError, match=r"^SOURCE_DATE_EPOCH='tomorrow': expected a whole"):
        local_time()
    stamp = local_time(strict=False)  # a run's stale banner: the clock's time
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d [+-]\d{4}", stamp), stamp


def test_the_summary_and_manoeuvre_tables_read_to_a_screen_reader() -> None:
    """A screen reader announced the tables' rows without a caption or a header's scope,
    and the manoeuvre metrics as "advance_m 10.27": the unit a word of the name where
    the key figures beside them say "(m)"."""
    summary = {
        "scenario": "turning-circle",
        "status": "complete",
        "stop_time": 60.0,
        "manoeuvre": "turning-circle",
        "advance_m": 10.27,
        "steady_roll_deg": None,
        "speed_loss_pct": 3.5,
        "key_figures": {"peak_abs_mass_position_m": 0.06},
    }
    page = index_page(Path("runs/turning-circle"), summary, None, {})
    assert problems(page) == []
    assert [bool(t.caption) for t in read_page(page).tables] == [True, True]
    assert '<th scope="row">advance (m)</th><td>10.27</td>' in page
    assert '<th scope="row">speed loss (%)</th><td>3.5</td>' in page
    assert '<th scope="row">steady roll (deg)</th><td>n/a</td>' in page


@pytest.mark.slow
def test_each_figure_of_a_report_has_an_alt_text_saying_what_it_shows(lateral_run) -> None:
    """The figures' alt texts were their file names ("attitude_actuators"): a screen
    reader said that and nothing of what the figure plots."""
    page = write_report(lateral_run).read_text()
    assert problems(page) == []
    alts = dict(read_page(page).images)
    assert "u (m/s)" in alts["velocities.png"] and "time (s)" in alts["velocities.png"]
    assert "phi (deg)" in alts["attitude_actuators.png"]
    assert "north (m)" in alts["trajectory.png"] and "east (m)" in alts["trajectory.png"]


@pytest.mark.slow
@pytest.mark.viewer  # starts a browser
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt, .ci/run)")
def test_a_long_run_folder_name_does_not_make_a_phone_scroll_sideways(tmp_path: Path) -> None:
    """The page names its run folder in one <code> word: a folder such as
    runs_of_the_survey/survey_at_two_metres_in_a_cross_current made the whole page 501 px
    wide in a 375 px window."""
    pytest.importorskip("playwright.sync_api", reason="needs playwright (test extra)")
    run_dir = Path("runs_of_the_survey/survey_at_two_metres_in_a_cross_current_of_0.2_m_s")
    page = tmp_path / "index.html"
    page.write_text(index_page(run_dir, {"scenario": "survey"}, None, {}), "utf-8")
    (tmp_path / "profile").mkdir()
    assert overflow(page, tmp_path / "profile") == []


def test_each_figure_names_its_scenario_in_its_title(lateral_run, monkeypatch) -> None:
    """A figure lifted into a paper says what was run: its title names the scenario id."""
    kept = kept_figures(lateral_run, monkeypatch)
    assert set(kept) >= {"velocities.png", "attitude_actuators.png", "trajectory.png"}
    for name, fig in kept.items():
        assert "open-loop" in fig.get_suptitle(), f"{name}: {fig.get_suptitle()!r}"
        assert "did not complete" not in fig.get_suptitle()


def test_a_figure_of_an_incomplete_run_says_so_and_spans_the_stop_time(
    tmp_path, monkeypatch
) -> None:
    """A run that stopped at 2 s of 10: each figure's title says it did not complete and
    where it stopped, and the time axes run from 0 to the 10 s stop time (they ended at
    2 s, drawing a partial run as though it were all of it)."""
    summary = {"scenario": "broken", "status": "incomplete", "complete": False,
               "stop_time": 10.0, "time_reached": 2.0}  # fmt: skip
    run = _write_run(tmp_path / "broken", Variant.LATERAL, {"u": 1.5}, {}, 2.0, summary)
    kept = kept_figures(run, monkeypatch)
    for name, fig in kept.items():
        title = fig.get_suptitle()
        assert "broken" in title and "did not complete" in title, f"{name}: {title!r}"
        assert "t = 2 of 10 s" in title, f"{name}: {title!r}"
    for name in ("velocities.png", "attitude_actuators.png"):
        times = [ax for ax in kept[name].axes if ax.get_ylabel()]
        assert all(ax.get_xlim() == pytest.approx((0.0, 10.0)) for ax in times), name


def test_the_track_is_named_in_the_legend_of_the_trajectory_and_deviation(
    lateral_run, monkeypatch
) -> None:
    """The vehicle's path is the main line of the trajectory and the lateral deviation
    figures: their legends named the start, the end and the initial course but not it."""
    kept = kept_figures(lateral_run, monkeypatch)
    for name in ("trajectory.png", "lateral_deviation.png"):
        ax = kept[name].axes[0]
        longest = max(ax.lines, key=lambda line: len(line.get_xdata()))
        legend = [t.get_text() for t in ax.get_legend().get_texts()]
        assert longest.get_label() in legend, f"{name}: {longest.get_label()!r} not in {legend}"


def test_markers_of_different_events_are_told_apart_and_a_repeated_one_is_not() -> None:
    """A zigzag's "to-port" and "to-starboard" events were both solid orange lines: the
    legend named two lines a reader could not tell apart on the plot."""
    from cosim.viz.report import markers_of

    events = [{"name": name, "time": t} for t, name in
              enumerate(["to-port", "to-starboard", "to-port", "third", "fourth"])]  # fmt: skip
    markers = markers_of({"events": events})
    look = {m.label: (m.color, m.style) for m in markers}
    assert len(set(look.values())) == len(look) == 4, look
    again = [(m.color, m.style) for m in markers if m.label == "event to-port"]
    assert again[0] == again[1]
    settled = markers_of({"key_figures": {"yaw_settling_time_s": 2.0}, "events": events})[0]
    assert (settled.color, settled.style) not in look.values()


def test_a_faults_markers_say_when_it_starts_and_stops() -> None:
    """A fault's markers read "fault jam (mass-jam) starts": its time was to be guessed
    from the axis, where the settling time's marker gives its own ("yaw settled (3.21 s)")."""
    from cosim.viz.report import markers_of

    fault = {"name": "jam", "kind": "stuck", "target": "plant.fin_angle", "start": 3.0, "stop": 7.5}
    labels = [m.label for m in markers_of({"faults": [fault]})]
    assert labels == ["fault jam (stuck) starts (3 s)", "fault jam (stuck) stops (7.5 s)"]


def test_the_stern_plane_limit_is_drawn_on_its_panel(tmp_path, monkeypatch) -> None:
    """The stern planes of a depth run sat on their 25 deg stops with no line marking
    them, while the mass stops and the thruster limit had theirs."""
    run = _write_run(tmp_path / "run", Variant.FULL, {"u": 1.5}, {"fin_angle": 0.2},
                     summary={"scenario": "dive"})  # fmt: skip
    (run / "scenario.toml").write_text(
        '[instances.controller]\nfmu = "AuvAutopilot"\n'
        "[instances.controller.start]\nfin_angle_limit = 0.3\n"
    )
    kept = kept_figures(run, monkeypatch)
    fins = next(ax for ax in kept["depth.png"].axes if ax.get_ylabel() == r"$\delta_s$ (deg)")
    levels = sorted(line.get_ydata()[0] for line in fins.lines if line.get_linestyle() == ":")
    assert levels == pytest.approx([-np.degrees(0.3), np.degrees(0.3)])


def test_a_set_point_its_fmu_declares_in_degrees_is_drawn_unscaled(tmp_path, monkeypatch) -> None:
    """Another tool's autopilot whose yaw_setpoint is in deg (summary.json's units say so):
    its 20 deg set-point was drawn as 1146 deg on the yaw panel, scaled as if in rad."""
    run = tmp_path / "run"
    run.mkdir()
    rows = "".join(f"{t},0.1,20.0\n" for t in (0.0, 0.1, 0.2))
    (run / "results.csv").write_text("time,plant.yaw,controller.yaw_setpoint\n" + rows)
    units = {"time": "s", "plant.yaw": "rad", "controller.yaw_setpoint": "deg"}
    (run / "summary.json").write_text(json.dumps({"units": units}))
    kept = kept_figures(run, monkeypatch)
    yaw = next(ax for ax in kept["attitude_actuators.png"].axes if "psi" in ax.get_ylabel())
    drawn = {line.get_label().split(" (")[0]: line.get_ydata() for line in yaw.lines}
    assert list(drawn["setpoint"]) == pytest.approx([20.0] * 3)  # deg, as declared
    assert list(drawn["yaw"]) == pytest.approx([math.degrees(0.1)] * 3)  # rad, drawn in deg


def test_a_thruster_off_fault_draws_the_force_the_plant_got(tmp_path, monkeypatch) -> None:
    """A run with a thruster-off fault (the lab's exercise) drew the autopilot's command
    on the F_t panel alone: 8 N of thrust after the thruster had failed. While the fault
    acts the plant gets 0 N (docs/events.md); the panel draws that force beside the
    command (under Jacobi the command of each row; none from the last row, where no step
    starts)."""
    run = tmp_path / "run"
    run.mkdir()
    rows = "".join(
        f"{t},{f},{int(t >= 0.2)}\n" for t, f in ((0.0, 5.0), (0.1, 6.0), (0.2, 7.0), (0.3, 8.0))
    )
    (run / "results.csv").write_text("time,controller.tunnel_force,fault.thruster\n" + rows)
    fault = {"name": "thruster", "kind": "thruster-off", "target": "plant.tunnel_force",
             "start": 0.2, "stop": None}  # fmt: skip
    (run / "summary.json").write_text(json.dumps({"faults": [fault]}))
    (run / "scenario.toml").write_text(
        'faults = [{ name = "thruster", kind = "thruster-off", start = 0.2 }]\n'
        '[coupling]\nstep = 0.1\nalgorithm = "jacobi"\n'
        '[connections]\nadd = [{ from = "controller.tunnel_force", to = "plant.tunnel_force" }]\n'
    )
    kept = kept_figures(run, monkeypatch)
    force = next(ax for ax in kept["attitude_actuators.png"].axes if "F_t" in ax.get_ylabel())
    drawn = {line.get_label(): list(line.get_ydata()) for line in force.lines}
    delivered = drawn["delivered to plant.tunnel_force (N)"]
    np.testing.assert_array_equal(delivered, [5.0, 6.0, 0.0, np.nan])
    assert drawn["controller.tunnel_force as sent (N)"] == pytest.approx([5.0, 6.0, 7.0, 8.0])
    page = (run / "report" / "index.html").read_text(encoding="utf-8")
    assert "F_t (N) with delivered to plant.tunnel_force (N)" in page, page  # the alt text


def test_a_report_made_elsewhere_finds_the_limits_of_the_fmus_the_run_used(
    fmu_paths: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run on FMUs outside the working folder's build/fmus (``--fmu-dir``, or a run
    started in another folder) was reported without the mass stops and the thruster
    limit: the report looked for the built-in FMUs' declared limits in build/fmus of the
    folder it was made from. It reads them from the FMUs the run used."""
    from cosim.viz import report

    monkeypatch.chdir(tmp_path)  # no build/fmus here
    fmus = str(fmu_paths["AuvPlant"].parent)
    argv = ["run", "bs-3", "--stop-time", "0.1", "--no-rrd", "--quiet", "--out", "run"]
    assert main([*argv, "--fmu-dir", fmus]) == 0
    assert report.actuator_limits(tmp_path / "run") == {
        "plant.mass_position": pytest.approx(0.06),  # m, the REMUS 100's rail stops
        "controller.tunnel_force": pytest.approx(10.0),  # N, the autopilot's limit
        "controller.fin_angle": pytest.approx(math.radians(25.0)),  # the stern planes' stops
    }


def test_a_limits_legend_names_its_unit_and_the_transients_title_a_readable_time(
    tmp_path, monkeypatch
) -> None:
    """The thruster's legend read "limit +-8" (8 what?) and the transient column's title
    "first 9.62194 s" (digits of a time nobody reads to a microsecond)."""
    run = _settled_run(tmp_path / "run", 1.654321)
    fig = kept_figures(run, monkeypatch)["attitude_actuators.png"]
    titles = [ax.get_title() for ax in fig.axes]
    assert "the transient: first 4.96 s" in titles, titles
    thruster = next(ax for ax in fig.axes if ax.get_ylabel() == "$F_t$ (N)")
    assert "limit +-8 N" in [t.get_text() for t in thruster.get_legend().get_texts()]
    mass = next(ax for ax in fig.axes if ax.get_ylabel() == "$y_v$ (cm)")
    assert "limit +-5 cm" in [t.get_text() for t in mass.get_legend().get_texts()]


def test_a_fault_campaigns_page_lists_the_faults_and_says_why_a_figure_is_missing(
    tmp_path: Path,
) -> None:
    """A fault-recovery run's page gave "heading error at fault (deg) 4.3" without the
    fault's time or what failed (only the figures' markers named it), and left out the
    yaw settling time altogether when the heading never settled, as if it were not
    measured. The page lists each fault (name, kind, target, start, stop) and each event
    fired, and a key figure summary.json holds as null with the reason."""
    run = tmp_path / "run"
    run.mkdir()
    rows = "".join(f"{t},0.5,0.0,{int(t >= 0.2)}\n" for t in (0.0, 0.1, 0.2, 0.3))
    (run / "results.csv").write_text("time,plant.yaw,controller.yaw_setpoint,fault.jam\n" + rows)
    summary = {
        "scenario": "mass-jam",
        "status": "complete",
        "complete": True,
        "key_figures": {"yaw_settling_time_s": None},
        "events": [{"name": "turn", "time": 0.1, "set": {"controller.yaw_setpoint": 0.0}}],
        "faults": [
            {
                "name": "jam",
                "kind": "mass-jam",
                "target": "plant.mass_position_cmd",
                "start": 0.2,
                "stop": None,
            },
        ],
    }
    (run / "summary.json").write_text(json.dumps(summary))
    page = write_report(run).read_text(encoding="utf-8")
    assert problems(page) == []
    assert "<caption>Faults" in page and "<caption>Events fired" in page, page
    assert (
        '<th scope="row">jam</th><td>mass-jam</td><td>plant.mass_position_cmd</td>'
        "<td>0.2</td><td>never: to the end of the run</td>"
    ) in page, page
    assert '<th scope="row">turn</th><td>0.1</td><td>controller.yaw_setpoint = 0</td>' in page
    assert (
        '<th scope="row">yaw settling time (s)</th><td>none (not settled: the yaw is not '
        "within 1 deg of its set-point at the end)</td>"
    ) in page, page


def test_a_report_past_the_file_size_limit_names_the_limit(tmp_path, run_python) -> None:
    """Under ``ulimit -f`` a report said "cannot write the report into DIR: File too
    large", as if a disk were full, naming no limit."""
    run = _sparse_run(tmp_path / "run", ("plant.u", "plant.roll"))
    code = """
        import resource, sys
        from cosim.cli import main
        resource.setrlimit(resource.RLIMIT_FSIZE, (2000, resource.RLIM_INFINITY))
        sys.exit(main(["report", sys.argv[1]]))
    """
    done = run_python(code, run)
    assert done.returncode == 1, done.stderr
    assert done.stderr == (
        f"auv-cosim report: cannot write the report into {run / 'report'}: File too large: "
        "the file-size limit of this process, 2000 bytes (ulimit -f), stopped it: raise it "
        "(ulimit -f unlimited); nothing of it is left (no report made)\n"
    )
    assert not (run / "report").exists()


@pytest.mark.parametrize(
    ("yaw_deg", "setpoint_deg", "drawn_deg"),
    [(370.0, 10.0, 370.0), (-90.0, 270.0, -90.0), (179.0, -179.0, 181.0)],
)
def test_a_yaw_set_point_is_drawn_on_the_yaws_own_turn(
    tmp_path, monkeypatch, yaw_deg, setpoint_deg, drawn_deg
) -> None:
    """The plant's yaw counts whole turns (a turn from 350 to 10 deg ends at 370 deg) and
    the autopilot wraps its error, so 270 and -90 deg are one heading: the set-point was
    drawn a full turn away from the yaw it held, off the panel's axis ("beyond the
    axis"), and the operator saw no set-point at all. It is drawn on the yaw's turn."""
    run = tmp_path / "run"
    run.mkdir()
    setpoint = math.radians(setpoint_deg)
    rows = "".join(  # the yaw comes up to its set-point by 4 deg
        f"{t},{math.radians(yaw_deg - 4.0 + 20.0 * t)!r},{setpoint!r}\n" for t in (0.0, 0.1, 0.2)
    )
    (run / "results.csv").write_text("time,plant.yaw,controller.yaw_setpoint\n" + rows)
    kept = kept_figures(run, monkeypatch)
    panel = next(ax for ax in kept["attitude_actuators.png"].axes if "psi" in ax.get_ylabel())
    drawn = {line.get_label(): line.get_ydata() for line in panel.lines}
    assert list(drawn["setpoint"]) == pytest.approx([drawn_deg] * 3), drawn


def test_a_yaw_set_point_half_a_turn_away_is_drawn_where_the_autopilot_turns(
    tmp_path, monkeypatch
) -> None:
    """A set-point half a turn from the yaw (180 deg from 0: a U-turn) is one the autopilot
    takes as -180 deg, its error lying in [-180, 180) deg, and it turns that way; the
    report put the first sample at +180 deg, then, once the yaw had moved, at -180 deg:
    a line across the whole panel at the turn's start, on the side the vehicle never
    went. The set-point is drawn on the turn the autopilot steers for, all along."""
    run = tmp_path / "run"
    run.mkdir()
    setpoint = math.radians(180.0)
    rows = "".join(  # the yaw turns the autopilot's way, negative, most of the way
        f"{t},{math.radians(yaw)!r},{setpoint!r}\n"
        for t, yaw in ((0.0, 0.0), (5.0, -90.0), (10.0, -170.0))
    )
    (run / "results.csv").write_text("time,plant.yaw,controller.yaw_setpoint\n" + rows)
    kept = kept_figures(run, monkeypatch)
    panel = next(ax for ax in kept["attitude_actuators.png"].axes if "psi" in ax.get_ylabel())
    drawn = {line.get_label(): line.get_ydata() for line in panel.lines}
    assert list(drawn["setpoint"]) == pytest.approx([-180.0] * 3), drawn


def test_a_renamed_vehicles_unsettled_yaw_reads_not_settled(tmp_path: Path) -> None:
    """One vehicle whose instances are named auv and ap (not plant and controller): its
    page gave the yaw settling time's reason as "not recorded", its yaw recorded as
    auv.yaw; the reason is the one a run of the built-in names gets, "not settled"."""
    (tmp_path / "results.csv").write_text(
        "time,auv.yaw,ap.yaw_setpoint\n0,0.5,0\n1,0.3,0\n", encoding="utf-8"
    )
    summary = {
        "scenario": "renamed",
        "status": "complete",
        "complete": True,
        "fmus": {"auv": {"model": "AuvPlant"}, "ap": {"model": "AuvAutopilot"}},
        "key_figures": {"yaw_settling_time_s": None},
    }
    (tmp_path / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    page = write_report(tmp_path).read_text(encoding="utf-8")
    assert (
        '<th scope="row">yaw settling time (s)</th><td>none (not settled: the yaw is not '
        "within 1 deg of its set-point at the end)</td>"
    ) in page, re.findall(r"yaw settling time \(s\)</th><td>[^<]*", page)


def test_a_vehicles_figures_mark_no_fault_or_event_of_another_vehicle(tmp_path) -> None:
    """Two vehicles, a fault jamming plant_b's mass and an event on plant_b's current:
    plant_a's figures marked them too, as if they acted on plant_a. Each vehicle's figures
    mark its own and those of no vehicle in particular (an event on a guidance)."""
    from cosim.viz.report import vehicle_views

    fmus = {name: {"model": "AuvPlant"} for name in ("plant_a", "plant_b")}
    jam = {"name": "jam", "kind": "mass-jam", "target": "plant_b.mass_position_cmd", "start": 1}
    gust = {"name": "gust", "time": 2.0, "set": {"plant_b.current_east": 0.3}}
    leg = {"name": "leg", "time": 3.0, "set": {"guidance.lookahead": 4.0}}
    summary = {"fmus": fmus, "faults": [jam], "events": [gust, leg]}
    a, b = vehicle_views(tmp_path, summary)
    assert (a.plant, b.plant) == ("plant_a", "plant_b")
    assert a.summary(summary)["faults"] == [] and a.summary(summary)["events"] == [leg]
    assert b.summary(summary)["faults"] == [jam] and b.summary(summary)["events"] == [gust, leg]
