"""``auv-cosim report`` of a run with faults: each panel that draws a faulted connection's
source also draws what the fault delivered to its target, the fault's interval shaded.

The runs here are short runs of the built FMUs that also record the faulted inputs
themselves (a connected input read after its instance's step holds the value the master
delivered for that step), so the line the report draws is checked against what the
vehicle actually got, for every fault kind that changes a connection's value.
"""

from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np
import pytest
from report_figures import kept_figures

from cosim.cli import main
from cosim.outputs.results import read_csv
from cosim.scenario.spec import SCENARIO_FOLDER

pytestmark = pytest.mark.fmu

# kind -> (the scenario it runs on, the faults' TOML, the faulted input, the panel's label,
# the scale from SI to the panel's unit)
CASES = {
    "stuck": ("bs-3", 'target = "plant.mass_position_cmd"', "plant.mass_position_cmd",
              "$y_v$ (cm)", 100.0),
    "bias": ("bs-3", 'target = "plant.tunnel_force"\nvalue = 2.0', "plant.tunnel_force",
             "$F_t$ (N)", 1.0),
    "gain": ("bs-3", 'target = "plant.tunnel_force"\nvalue = 0.5', "plant.tunnel_force",
             "$F_t$ (N)", 1.0),
    "noise": ("bs-3", 'target = "controller.yaw"\nstd = 0.01\nseed = 3', "controller.yaw",
              r"$\psi$ (deg)", math.degrees(1.0)),
    "delay": ("bs-3", 'target = "plant.tunnel_force"\nsteps = 3', "plant.tunnel_force",
              "$F_t$ (N)", 1.0),
    "dropout": ("bs-3", 'target = "plant.mass_position_cmd"\nprobability = 0.5\nseed = 2',
                "plant.mass_position_cmd", "$y_v$ (cm)", 100.0),
    "mass-jam": ("bs-3", "", "plant.mass_position_cmd", "$y_v$ (cm)", 100.0),
    "thruster-off": ("bs-3", "", "plant.tunnel_force", "$F_t$ (N)", 1.0),
    "plane-stuck": ("vert-2", "", "plant.fin_angle", r"$\delta_s$ (deg)",
                    math.degrees(1.0)),
}  # fmt: skip


def _faulty_run(
    tmp_path: Path, fmu_dir: Path, kind: str, algorithm: str = "gauss-seidel"
) -> tuple[Path, str]:
    """A 1.2 s run of the case's scenario with the fault acting from 0.3 s to 0.8 s,
    recording the faulted input beside the usual columns; its folder and the input."""
    base, keys, target, _, _ = CASES[kind]
    text = (SCENARIO_FOLDER / f"{base}.toml").read_text(encoding="utf-8")
    text = text.replace("stop_time = 60.0", "stop_time = 1.2")
    text = text.replace('algorithm = "gauss-seidel"', f'algorithm = "{algorithm}"')
    # vert-2 from on its depth set-point: the stern planes move, off their stops
    text = text.replace("v_0 = 0.10                        # m/s", "v_0 = 0.10\ndown_0 = 1.0")
    scenario = tmp_path / f"{kind}.toml"
    scenario.write_text(
        text
        + f'\n[[faults]]\nname = "f"\nkind = "{kind}"\n{keys}\nstart = 0.3\nstop = 0.8\n'
        + "\n[output]\nrecord = ['plant.yaw', 'plant.mass_position', 'plant.down', "
        + "'controller.mass_position_cmd', 'controller.tunnel_force', 'controller.fin_angle', "
        + f"'controller.depth_setpoint', 'controller.yaw_setpoint', '{target}']\n",
        encoding="utf-8",
    )
    out = tmp_path / "run"
    argv = ["run", str(scenario), "--no-rrd", "--quiet", "--out", str(out)]
    assert main([*argv, "--fmu-dir", str(fmu_dir)]) == 0
    return out, target


def _panels(run: Path, monkeypatch: pytest.MonkeyPatch) -> list:
    """Every axis of the report's time-history figures, as matplotlib draws them."""
    kept = kept_figures(run, monkeypatch)
    return [ax for fig in kept.values() for ax in fig.axes]


@pytest.mark.parametrize("kind", sorted(CASES))
def test_a_faults_panel_draws_what_the_target_got_beside_what_was_sent(
    kind: str, fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Only a thruster-off fault had its delivered value drawn: a jammed mass, a stuck or
    delayed command, a biased or noisy sensor were drawn as the autopilot sent them, so a
    reader could not see what the vehicle got. Each kind's panel draws the delivered
    value (the value the target held from each row's time on), the legend naming sent
    and delivered with the panel's unit, and the fault's interval shaded."""
    run, target = _faulty_run(tmp_path, fmu_dir, kind)
    _, _, _, ylabel, scale = CASES[kind]
    columns, values = read_csv(run / "results.csv")
    got = values[:, columns.index(target)] * scale  # row n + 1: the delivery at point n
    axis = next(ax for ax in _panels(run, monkeypatch) if ax.get_ylabel() == ylabel)
    lines = {  # (a line's label says when part of it lies beyond the axis)
        str(line.get_label()).removesuffix(" (beyond the axis)"): np.asarray(line.get_ydata())
        for line in axis.lines
    }
    unit = ylabel.rpartition("(")[2].rstrip(")")
    name = f"delivered to {target} ({unit})"
    delivered = next((v for label, v in lines.items() if label.startswith(name)), None)
    assert delivered is not None, f"{kind}: no line {name!r} among {sorted(lines)}"
    np.testing.assert_allclose(delivered[:-1], got[1:], rtol=1e-12, atol=1e-12)
    source = next(v for label, v in lines.items() if "as sent" in label)
    assert np.any(np.abs(delivered[:-1] - source[1:]) > 1e-9), "the fault changed nothing"
    sent = [label for label in lines if "sent" in label]
    assert sent and all(label.endswith(f"({unit})") for label in sent), sorted(lines)
    legend = [text.get_text() for text in axis.get_legend().get_texts()]
    assert f"fault f ({kind}) acting" in legend, legend
    shaded = [p for p in axis.patches if p.get_label() == f"fault f ({kind}) acting"]
    assert shaded, [p.get_label() for p in axis.patches]
    start, width = shaded[0].get_x(), shaded[0].get_width()
    assert (start, start + width) == pytest.approx((0.3, 0.8))


def test_under_jacobi_the_delivered_value_is_the_one_gathered_a_step_before(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Under Jacobi the plant takes the command the autopilot gave at the step before
    (Gauss-Seidel: the one it gives at this step): a delay fault's delivered line follows
    the run's own order of delivery."""
    run, target = _faulty_run(tmp_path, fmu_dir, "delay", algorithm="jacobi")
    columns, values = read_csv(run / "results.csv")
    got = values[:, columns.index(target)]
    axis = next(ax for ax in _panels(run, monkeypatch) if ax.get_ylabel() == "$F_t$ (N)")
    delivered = next(
        np.asarray(line.get_ydata())
        for line in axis.lines
        if str(line.get_label()).startswith(f"delivered to {target}")
    )
    np.testing.assert_allclose(delivered[:-1], got[1:], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    ("target", "record", "why"),
    [
        # the autopilot's thrust: recorded, but no panel of the report draws it
        ("plant.thrust", "'controller.thrust', 'plant.yaw'",
         "no panel of this report draws its source controller.thrust"),
        # the tunnel force, its source left out of results.csv
        ("plant.tunnel_force", "'plant.yaw'",
         "results.csv does not record its source controller.tunnel_force"),
    ],
)  # fmt: skip
def test_a_faulted_connection_the_report_cannot_draw_is_named_on_its_page(
    target: str, record: str, why: str, fmu_dir: Path, tmp_path: Path
) -> None:
    """A fault on a connection whose source no panel draws (the thrust) or the run did
    not record: the report drew nothing of it and said nothing, so a reader took the
    figures for the whole story. The page names the fault, its connection and why its
    delivered value is not drawn."""
    text = (SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8")
    scenario = tmp_path / "undrawn.toml"
    scenario.write_text(
        text.replace("stop_time = 60.0", "stop_time = 0.5")
        + f'\n[[faults]]\nname = "f"\nkind = "gain"\ntarget = "{target}"\nvalue = 0.5\n'
        + f"\n[output]\nrecord = [{record}]\n",
        encoding="utf-8",
    )
    out = tmp_path / "run"
    argv = ["run", str(scenario), "--no-rrd", "--quiet", "--out", str(out)]
    assert main([*argv, "--fmu-dir", str(fmu_dir)]) == 0
    assert main(["report", str(out)]) == 0
    page = html.unescape((out / "report" / "index.html").read_text(encoding="utf-8"))
    source = why.rpartition(" ")[2]
    assert f"fault f (gain) on {source} -> {target}: not drawn, {why}" in page, page
