"""A study's figures drafted before its last row (their panels and ticks, made while the
last run runs) are the figures drawn without a draft, byte for byte; a draft the last
rows no longer fit is left unused."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from cosim.study import plots

CAPTION = "study s (bs-3)"
V0 = [round(-0.1 + 0.2 * i / 15, 4) for i in range(16)]  # the benchmark's 16 values
K0 = [0.2, 0.5, 1.0]


def _row(v: float, k: float, sample: int = 0) -> dict[str, Any]:
    return {
        "plant.v_0": v, "controller.k0": k, "plant.current_east": 0.01 * sample,
        "yaw_settling_time_s": 2.0 + 3.0 * k + 10 * abs(v) + 0.1 * sample,
        "peak_abs_tunnel_force_N": 5.0 + k * abs(v) * 90 - 0.2 * sample,
        "peak_abs_mass_position_m": abs(v) / 3 + 0.001 * sample, "status": "complete",
    }  # fmt: skip


METRICS = ["yaw_settling_time_s", "peak_abs_tunnel_force_N", "peak_abs_mass_position_m"]
UNITS = {"plant.v_0": "m/s", "peak_abs_tunnel_force_N": "N", "yaw_settling_time_s": "s",
         "peak_abs_mass_position_m": "m", "controller.k0": "1",
         "plant.current_east": "m/s"}  # fmt: skip
STUDIES = {
    # the benchmark's: one factor of 16 values (ticks placed by matplotlib), three panels
    "one factor": ({"plant.v_0": V0}, [], [_row(v, 0.5) for v in V0]),
    # two factors of a few values each (ticks at the values), a legend, lines that
    # coincide (+-v0) named in a note
    "two factors": (
        {"plant.v_0": [-0.1, 0.1], "controller.k0": K0},
        [],
        [_row(v, k) for v in (-0.1, 0.1) for k in K0],
    ),
    # a grid and samples: means over them, histograms, the scatter matrix (not drafted)
    "grid and samples": (
        {"plant.v_0": [-0.1, 0.05, 0.1]},
        ["plant.current_east"],
        [_row(v, 0.5, s) for v in (-0.1, 0.05, 0.1) for s in range(4)],
    ),
}
SLOW = {"grid and samples"}  # its scatter matrix, 16 panels drawn twice: ~5 s


def _pngs(folder: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir())}


@pytest.mark.parametrize(
    "study", [pytest.param(name, marks=[pytest.mark.slow] * (name in SLOW)) for name in STUDIES]
)
def test_figures_drawn_in_their_drafts_are_the_same_pngs(tmp_path: Path, study: str) -> None:
    """Each figure a draft holds is taken by the figure it was made for, and the PNG is
    the one drawn without it, byte for byte (a tick made ahead that the draw does not
    place stays undrawn)."""
    grid, randoms, rows = STUDIES[study]
    plain = plots.write_figures(rows, grid, randoms, METRICS, tmp_path / "plain", UNITS, CAPTION)
    drafts = plots.draft_figures(rows[:-1], grid, randoms, METRICS, CAPTION)
    assert len(drafts) == len(grid) + bool(randoms)  # the grid figures and histograms
    drafted = plots.write_figures(
        rows, grid, randoms, METRICS, tmp_path / "drafted", UNITS, CAPTION, drafts
    )
    assert len(drafts) == 0  # every draft taken
    assert list(drafted) == list(plain)
    assert _pngs(tmp_path / "drafted") == _pngs(tmp_path / "plain")


def test_a_draft_the_last_rows_no_longer_fit_is_left_unused(tmp_path: Path) -> None:
    """A metric constant in the rows so far varies with the last one: the figure has a
    panel more than its draft, which is left, and the figure is drawn as without it."""
    grid, _, rows = STUDIES["one factor"]
    rows = [{**row, "peak_abs_mass_position_m": 0.01} for row in rows]
    rows[-1]["peak_abs_mass_position_m"] = 0.02
    plain = plots.write_figures(rows, grid, [], METRICS, tmp_path / "plain", UNITS, CAPTION)
    drafts = plots.draft_figures(rows[:-1], grid, [], METRICS, CAPTION)
    drafted = plots.write_figures(rows, grid, [], METRICS, tmp_path / "drafted", UNITS,
                                  CAPTION, drafts)  # fmt: skip
    assert len(drafts) == 1 and list(drafted) == list(plain)
    assert _pngs(tmp_path / "drafted") == _pngs(tmp_path / "plain")


def test_nothing_is_drafted_before_a_metric_varies() -> None:
    """One row so far (or none): no metric has two values yet, no figure's panels known."""
    grid, _, rows = STUDIES["one factor"]
    assert len(plots.draft_figures(rows[:1], grid, [], METRICS, CAPTION)) == 0


@pytest.mark.cluster
@pytest.mark.slow
def test_a_sweep_draws_its_figures_in_the_drafts_made_beside_its_last_run(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The study drafts its page's figures once, from every row but the last (the last
    run still running), and its grid figure and histograms are drawn in those drafts."""
    from sweep_helpers import SMALL_RUNS, SMALL_STUDY, sweep

    from cosim.study import runner

    seen: list[int] = []
    taken: list[bool] = []
    draft_page, take = runner._draft_page, plots.Drafts.take

    def counted(*args: Any) -> plots.Drafts:
        seen.append(len(args[-1]))
        return draft_page(*args)

    def taking(self: plots.Drafts, n: int, figure_title: str) -> Any:
        found = take(self, n, figure_title)
        taken.append(found is not None)
        return found

    monkeypatch.setattr(runner, "_draft_page", counted)
    monkeypatch.setattr(plots.Drafts, "take", taking)
    study = tmp_path / "study.toml"
    study.write_text(SMALL_STUDY, encoding="utf-8")
    sweep(study, tmp_path / "out", fmu_dir, "--workers", "2")
    assert seen == [SMALL_RUNS - 1]
    assert taken == [True, True]  # the grid figure, the histograms
