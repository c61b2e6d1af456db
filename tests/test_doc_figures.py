"""scripts/doc_figures.py, which writes the numbers README.md and docs/ quote from the
built-in scenarios' runs: how it finds a marked figure, which metric it reads and how it
writes the number (the check of the pages against the runs themselves is in
tests/cosim/test_builtin_scenarios.py, which runs every scenario)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest
from repo_paths import ROOT, script_module


@pytest.fixture(scope="module")
def figures() -> ModuleType:
    return script_module("doc_figures")


def test_a_marker_names_the_scenario_and_the_metric_the_yaw_settling_time_by_default(
    figures: ModuleType, tmp_path: Path
) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "| bs-3 | settled after <!-- bs-3 -->3.21 s |\n"
        "overshoots <!-- zigzag-20:overshoot_1_deg -->0.88 / <!-- zigzag-20:overshoot_2_deg -->"
        "+1.35 deg\n<!-- run: expect 1.5 -->\n<!-- not run: 2.0 -->\n",
        encoding="utf-8",
    )
    found = [(f.scenario, f.metric, f.text) for f in figures.figures_in(page)]
    assert found == [
        ("bs-3", "yaw_settling_time_s", "3.21"),
        ("zigzag-20", "overshoot_1_deg", "0.88"),
        ("zigzag-20", "overshoot_2_deg", "+1.35"),
    ]  # the pages' other HTML comments (executed examples) are no figures


def test_a_figure_keeps_the_decimals_and_the_sign_the_page_gives_it(figures: ModuleType) -> None:
    assert figures.shown(0.86634, "0.88") == "0.87"
    assert figures.shown(96.62, "97") == "97"
    assert figures.shown(8.7062, "8.70") == "8.71"
    assert figures.shown(0.0012, "+0.00") == "+0.00"
    assert figures.shown(-0.0004, "0.00") == "0.00"  # no "-0.00"
    assert figures.shown(-0.26, "+0.1") == "-0.3"  # a negative value keeps its own sign
    assert figures.shown(39.47, "40") == "39"


def test_rewriting_replaces_the_numbers_and_keeps_the_markers(figures: ModuleType) -> None:
    text = "a <!-- bs-3 -->3.21 s, b <!-- mass-jam:heading_error_final_deg -->1.9 deg"
    values = {
        ("bs-3", "yaw_settling_time_s"): 3.2078,
        ("mass-jam", "heading_error_final_deg"): 1.86,
    }
    new = figures.rewrite(text, values)
    assert new == "a <!-- bs-3 -->3.21 s, b <!-- mass-jam:heading_error_final_deg -->1.9 deg"
    values[("mass-jam", "heading_error_final_deg")] = 2.04
    assert figures.rewrite(text, values).endswith(
        "<!-- mass-jam:heading_error_final_deg -->2.0 deg"
    )


def test_a_metric_the_run_lacks_or_never_reached_is_named(figures: ModuleType) -> None:
    key = {"yaw_settling_time_s": None, "peak_mass_position_m": 0.033}
    manoeuvre = {"manoeuvre": "zigzag", "overshoot_1_deg": 0.87}
    assert figures.metric_value("zigzag-20", "overshoot_1_deg", key, manoeuvre) == 0.87
    assert figures.metric_value("bs-3", "peak_mass_position_m", key, manoeuvre) == 0.033
    with pytest.raises(ValueError, match="bs-3: metric 'yaw_settling_time_s' is None"):
        figures.metric_value("bs-3", "yaw_settling_time_s", key, manoeuvre)
    expected = r"'period_s' is None in its run: expected a number, one of .*overshoot_1_deg"
    with pytest.raises(ValueError, match=expected):
        figures.metric_value("zigzag-20", "period_s", key, manoeuvre)


def test_the_pages_read_are_the_readme_and_the_docs(figures: ModuleType) -> None:
    pages = figures.pages(ROOT)
    assert pages[0] == ROOT / "README.md"
    assert ROOT / "docs" / "manoeuvres.md" in pages
    marked = {f.scenario for page in pages for f in figures.figures_in(page)}
    assert {"bs-3", "zigzag-20", "depth-steps", "survey"} <= marked


def test_a_marker_naming_no_scenario_is_refused_in_one_line(
    figures: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text("settles in <!-- bs-9 -->3.21 s\n", encoding="utf-8")
    assert figures.main([], root=tmp_path) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("doc_figures.py: ") and "'bs-9'" in err and "\n" not in err


def test_a_marker_may_name_a_figure_of_one_leg_of_a_survey(figures: ModuleType, tmp_path: Path):
    """manoeuvres.md gave the time the survey's last leg was completed, 185.6 s, by hand:
    a marker could name only a whole-run metric, not a figure of one of its ``legs``."""
    page = tmp_path / "page.md"
    page.write_text("the last at <!-- survey:legs.2.completed_at_s -->46.2 s\n", encoding="utf-8")
    [figure] = figures.figures_in(page)
    assert (figure.scenario, figure.metric, figure.text) == (
        "survey",
        "legs.2.completed_at_s",
        "46.2",
    )
    legs = [{"leg": 1, "completed_at_s": 31.34}, {"leg": 2, "completed_at_s": 46.2}]
    manoeuvre = {"manoeuvre": "survey", "legs_completed": 2, "legs": legs}
    assert figures.metric_value("survey", figure.metric, {}, manoeuvre) == 46.2  # counted from 1
    with pytest.raises(ValueError, match=r"^survey: metric 'legs\.3\.completed_at_s' is None"):
        figures.metric_value("survey", "legs.3.completed_at_s", {}, manoeuvre)
