"""The LQR loop's margins (``auv-cosim analyze margins``), each checked against an
independent reading: python-control's frequency response at the crossover the margin is
read at, and the closed-loop poles with the loop's gain scaled or its input delayed."""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path

import control
import numpy as np
import pytest
from unity_feedback import unity_feedback_poles

import cosim
from controller_fmu.depth_pd import DepthPd, sampled_loop_poles
from controller_fmu.lateral_model import LateralDesignModel
from controller_fmu.lqr import LqrHeading, delayed_poles
from cosim import cli
from cosim.analysis.margins import (
    LoopMargins,
    depth_loop,
    loop_margins,
    lqr_loop,
    scaled_vehicle,
)
from cosim.scenario.design_doubts import DesignWarning
from plant_fmu.model.parameters import load_vehicle

U0 = 1.525  # m/s, the shipped design speed
H = 0.01  # s, the shipped design step


@pytest.fixture(scope="module")
def loop() -> control.StateSpace:
    return lqr_loop(load_vehicle("remus100"), U0, H)


@pytest.fixture(scope="module")
def margins(loop: control.StateSpace) -> LoopMargins:
    return loop_margins(loop)


def _response(loop: control.StateSpace, omega: float) -> complex:
    return complex(np.asarray(control.frequency_response(loop, [omega]).complex).ravel()[0])


def _largest_pole(loop: control.StateSpace, factor: float = 1.0, delay: int = 0) -> float:
    """max |z| of the loop closed with its gain times ``factor`` and ``delay`` whole
    samples of delay at the plant input (python-control's series, closed as A - B C)."""
    delayed = control.tf([1.0], [1.0] + [0.0] * delay, H) if delay else 1.0
    return float(np.abs(unity_feedback_poles(control.series(delayed, factor * loop))).max())


def test_margins_read_where_the_frequency_response_crosses(
    loop: control.StateSpace, margins: LoopMargins
) -> None:
    """Every phase margin is read where |L| = 1, with 180 deg + the phase of L there, and
    every gain margin where L is real and negative, as -1 / L."""
    assert margins.stable and margins.phase_margins and margins.gain_margins
    for crossing in margins.phase_margins:
        at = _response(loop, crossing.frequency)
        assert abs(at) == pytest.approx(1.0, abs=1e-9)
        phase = math.degrees(np.angle(at))  # (-180, 180] deg
        assert crossing.value == pytest.approx(180.0 + phase if phase <= 0.0 else phase - 180.0)
    for crossing in margins.gain_margins:
        at = _response(loop, crossing.frequency)
        assert abs(at.imag) < 1e-9 * abs(at) and at.real < 0.0
        assert crossing.value == pytest.approx(-1.0 / at.real, rel=1e-9)


def test_gain_margins_bound_the_gains_the_closed_loop_stays_stable_at(
    loop: control.StateSpace, margins: LoopMargins
) -> None:
    """The LQR's loop (an unstable sway-yaw mode and a free heading) is stable for loop
    gains strictly between its lower and upper gain margins, and not just outside."""
    lower, upper = margins.lower_gain_margin, margins.upper_gain_margin
    assert lower is not None and upper is not None
    assert _largest_pole(loop, 1.001 * lower.value) < 1.0 < _largest_pole(loop, 0.999 * lower.value)
    assert _largest_pole(loop, 0.999 * upper.value) < 1.0 < _largest_pole(loop, 1.001 * upper.value)
    assert upper.frequency == pytest.approx(math.pi / H)  # the Nyquist frequency


def test_delay_margin_is_the_delay_the_loop_loses_stability_at(
    loop: control.StateSpace, margins: LoopMargins
) -> None:
    """Whole samples of delay at the plant input up to the delay margin keep the loop
    stable, one more does not; the shipped LQR takes none (its margin is under a step)."""
    delay = margins.delay_margin
    assert delay is not None
    steps = math.floor(delay.value / H)
    assert _largest_pole(loop, delay=steps) < 1.0 < _largest_pole(loop, delay=steps + 1)
    assert steps == 0


@pytest.mark.parametrize("step", [0.004, 0.01, 0.05])
def test_a_delay_within_a_step_is_taken_up_to_the_delay_margin(step: float) -> None:
    """The printed delay margin, read as PM / w_c, is exact for whole steps of delay; a
    delay of part of a step (the command held, as the modified z-transform of
    controller_fmu.lqr.delayed_poles computes it) keeps the loop stable up to the
    margin and past it by less than a tenth of a step, and a whole step beyond it does
    not."""
    remus = load_vehicle("remus100")
    lqr = LqrHeading(LateralDesignModel(remus, U0), step)
    delay = loop_margins(lqr_loop(remus, U0, step)).delay_margin
    assert delay is not None and delay.value < step

    def largest(late: float) -> float:
        return float(np.abs(delayed_poles(lqr.A, lqr.B, lqr.gain, step, late)).max())

    assert largest(delay.value) < 1.0 < largest(min(step, delay.value + 0.1 * step))


def test_the_depth_loop_is_the_autopilots_and_takes_its_delay_margin() -> None:
    """The depth PD's loop closes on the poles the autopilot's design check computes, and
    whole samples of delay up to its delay margin keep it stable, one more does not."""
    params = load_vehicle("remus100")
    depth = depth_loop(params, H, U0)
    margins = loop_margins(depth)
    expected = sampled_loop_poles(DepthPd(), params, U0, H)
    np.testing.assert_allclose(np.sort_complex(margins.poles), np.sort_complex(expected))
    delay = margins.delay_margin
    assert delay is not None
    steps = math.floor(delay.value / H)
    assert _largest_pole(depth, delay=steps) < 1.0 < _largest_pole(depth, delay=steps + 1)


def test_sensitivity_peak_is_the_largest_on_a_finer_grid(
    loop: control.StateSpace, margins: LoopMargins
) -> None:
    """Ms is no smaller than |1 / (1 + L)| anywhere on an independent grid up to pi/h."""
    omega = np.linspace(1e-3, math.pi / H, 20001)
    response = np.asarray(control.frequency_response(loop, omega).complex).ravel()
    assert margins.sensitivity_peak == pytest.approx(np.abs(1 / (1 + response)).max(), rel=1e-6)


def test_the_design_stays_on_the_nominal_vehicle_when_the_plant_is_scaled() -> None:
    """--scale changes the plant the loop is closed on, never the gain the autopilot
    designs on its own vehicle."""
    nominal = load_vehicle("remus100")
    heavier = scaled_vehicle(nominal, {"m_v": 1.2})
    assert heavier.m_v == pytest.approx(1.2 * nominal.m_v)
    gain = LqrHeading(LateralDesignModel(nominal, U0), H).gain
    np.testing.assert_array_equal(lqr_loop(nominal, U0, H, heavier).C.ravel(), gain)
    assert not np.allclose(lqr_loop(nominal, U0, H, heavier).A, lqr_loop(nominal, U0, H).A)


@pytest.mark.slow
@pytest.mark.filterwarnings("error::DeprecationWarning", "error::FutureWarning")
def test_the_command_prints_every_margin_with_its_unit(
    capsys: pytest.CaptureFixture, tmp_path: Path
) -> None:
    """`auv-cosim analyze margins` names each margin with its unit and where it is read,
    and --plot draws the Bode diagram into the file it names; with no deprecation warning
    (python-control 0.10.2 warns under NumPy 2.5 of each system without states it builds:
    the command builds none)."""
    bode = tmp_path / "bode.png"
    assert cli.main(["analyze", "margins", "--plot", str(bode)]) == 0
    assert bode.read_bytes().startswith(b"\x89PNG")
    out = capsys.readouterr().out
    expected_parts = (
        "gain margin, down: x ", " dB) at ", " rad/s", "phase margin: ", " deg at ",
        "delay margin: ", " s (", "steps of h", "Ms = ", "closed loop: stable",
    )  # fmt: skip
    for expected in expected_parts:
        assert expected in out, (expected, out)


@pytest.mark.parametrize(
    ("arguments", "refusal"),
    [
        (["--design-speed", "nan"], "--design-speed nan: expected a finite forward speed > 0 m/s"),
        (["--speed", "-1.5"], "--speed -1.5: expected a finite forward speed > 0 m/s"),
        (["--loop", "depth", "--speed", "nan"], "--speed nan: expected a finite forward speed"),
        (["--step", "0"], "--step 0.0: expected a finite sample time > 0 s"),
        (["--scale", "m_vv=1.2"], "--scale m_vv=1.2: unknown parameter 'm_vv'; expected one of"),
        (["--scale", "m_v=inf"], "--scale m_v=inf: expected a finite factor"),
        # the factor typed, not only the scaled value the vehicle's own check refused
        (
            ["--scale", "m=-1"],
            "--scale m=-1.0 (the vehicle's m = 30.5 times -1): m = -30.5: "
            "expected a number greater than 0",
        ),
    ],
)
def test_a_nonsensical_operating_point_is_refused_naming_it(
    capsys: pytest.CaptureFixture, arguments: list[str], refusal: str
) -> None:
    """A speed that is no forward speed, a step that is no sample time or a factor on no
    parameter is refused on one line naming the value and what is expected."""
    assert cli.main(["analyze", "margins", *arguments]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"auv-cosim analyze margins: {refusal}"), err
    assert err.count("\n") == 1


# --- the margins in the master: lqr-1 with a gain or delay fault on the servo command ---


# The DesignWarning a gain fault outside the margins gives (cosim.scenario.design_doubts)
OUTSIDE = (
    r"faults\.f: a gain of \S+ on plant\.mass_position_cmd .* outside that loop's gain margins"
)
ACTIVITY = "mass_position_cmd_variation_m_per_s"  # the command's key figure that shows it
CHATTERS = (
    OUTSIDE + r".* unstable at 314 rad/s .* swings between its limits at every step"
    rf".*\(the key figure {ACTIVITY}\) do$"
)
TURNS_AWAY = OUTSIDE + r".* unstable .*: its heading turns away, its error doubling every \S+ s"
# ... and a delay fault past the delay margin
LATE = r"faults\.f: a delay of 1 step .* past that loop's delay margin .* unstable, swinging at"


@contextmanager
def _no_design_doubt() -> Iterator[None]:
    """Fails on a DesignWarning: a fault within the margins is no design to doubt."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DesignWarning)
        yield


def _faulted_lqr_1(
    fmu_paths: dict[str, Path],
    out: Path,
    fault: str,
    stop: float,
    v0: float,
    said: AbstractContextManager[object],
) -> cosim.Run:
    """lqr-1 for ``stop`` s from a sway of ``v0`` m/s with the fault (``kind = ...`` and
    its keys) on the connection to plant.mass_position_cmd: the loop broken where
    `analyze margins` breaks it; the run (its results and summary), run inside ``said``
    (the warnings the run must, or must not, give)."""
    text = (Path(cosim.__file__).parent / "scenarios" / "lqr-1.toml").read_text()
    text = re.sub(r"(?m)^stop_time = \S+", f"stop_time = {stop!r}", text)
    text = re.sub(r"(?m)^v_0 = \S+", f"v_0 = {v0!r}", text)
    fault_table = f'\n[[faults]]\nname = "f"\ntarget = "plant.mass_position_cmd"\n{fault}\n'
    path = out / f"lqr-1-{len(list(out.iterdir()))}.toml"
    path.write_text(text + fault_table)
    with said:
        return cosim.run(path, fmu_dir=fmu_paths["AuvPlant"].parent)


def _fast_envelope(command: np.ndarray, windows: int) -> np.ndarray:
    """max |second difference| of the command in each of ``windows`` equal spans: the
    content near the Nyquist frequency and the 105 rad/s crossover, not the slow turn."""
    second = np.abs(np.diff(command, 2))
    return np.array([span.max() for span in np.array_split(second, windows)])


def _peak_frequency(command: np.ndarray, first: int, last: int) -> float:
    """The frequency (rad/s) of the largest content of the command's second difference
    over samples ``first`` to ``last`` (a Hann window, zero-padded to 8192 samples)."""
    span = np.diff(command, 2)[first:last]
    spectrum = np.abs(np.fft.rfft(span * np.hanning(span.size), 8192))
    return float(np.fft.rfftfreq(8192, H)[np.argmax(spectrum)] * 2 * math.pi)


@pytest.mark.slow
def test_the_simulated_loop_loses_stability_past_the_upper_gain_and_delay_margins(
    fmu_paths: dict[str, Path], tmp_path: Path, margins: LoopMargins, loop: control.StateSpace
) -> None:
    """In the master, a gain fault of 0.9 times the upper gain margin leaves lqr-1's fast
    content decaying, and 1.1 times makes it oscillate at the Nyquist frequency pi/h the
    margin is read at, up to the command's +-100 m limit; one step of delay (a delay
    fault, past the delay margin of 0.987 steps) makes it grow at the frequency of the
    delayed linear loop's unstable pole (104 rad/s, near the 105 rad/s crossover). The
    run says so before for the gain past the margin (a DesignWarning), not for 0.9."""
    upper, delay = margins.upper_gain_margin, margins.delay_margin
    assert upper is not None and delay is not None and delay.value < H
    done = {
        name: _faulted_lqr_1(fmu_paths, tmp_path, fault, 6.0, -0.01, said)
        for name, fault, said in (
            ("below", f'kind = "gain"\nvalue = {0.9 * upper.value!r}', _no_design_doubt()),
            (
                "above",
                f'kind = "gain"\nvalue = {1.1 * upper.value!r}',
                pytest.warns(DesignWarning, match=CHATTERS),
            ),
            ("late", 'kind = "delay"\nsteps = 1', pytest.warns(DesignWarning, match=LATE)),
        )
    }
    runs = {name: run.results["controller.mass_position_cmd"] for name, run in done.items()}
    # the command's activity, the key figure the gain fault's warning names, shows it
    activity = {n: run.summary["key_figures"][ACTIVITY] for n, run in done.items()}
    assert activity["above"] > 1e3 * activity["below"], activity
    below, above, late = (_fast_envelope(runs[n].to_numpy(), 6) for n in ("below", "above", "late"))
    assert below[-1] < 1e-3 * below[0] and late[-1] > 5 * late[0]
    assert above[-1] == pytest.approx(400.0)  # +-100 m, alternating every step
    nyquist = _peak_frequency(runs["above"].to_numpy(), 100, 600)
    assert nyquist == pytest.approx(upper.frequency, rel=0.01)
    delayed = control.series(control.tf([1.0], [1.0, 0.0], H), loop)
    unstable = max(unity_feedback_poles(delayed), key=abs)
    frequency = _peak_frequency(runs["late"].to_numpy(), 200, 600)  # 2 to 6 s: growing
    assert frequency == pytest.approx(abs(np.angle(unstable)) / H, rel=0.02)


@pytest.mark.slow
def test_the_simulated_heading_grows_below_the_lower_gain_margin_as_the_linear_loop(
    fmu_paths: dict[str, Path], tmp_path: Path, margins: LoopMargins, loop: control.StateSpace
) -> None:
    """In the master, lqr-1 from a 1e-6 m/s sway (small: the yaw drag N_rr r |r| is first
    order in the turn rate) with a gain fault of 0.8 times the lower gain margin turns
    away at the rate (1/s) of the linear loop's slow unstable pole at that gain, and with
    1.25 times comes back at the rate of its slowest pole, each within 25 %. The run
    says so before for 0.8 (a DesignWarning), not for 1.25."""
    lower = margins.lower_gain_margin
    assert lower is not None
    for factor in (0.8, 1.25):
        gain = factor * lower.value
        said = pytest.warns(DesignWarning, match=TURNS_AWAY) if factor < 1 else _no_design_doubt()
        results = _faulted_lqr_1(
            fmu_paths, tmp_path, f'kind = "gain"\nvalue = {gain!r}', 200.0, -1e-6, said
        ).results
        yaw = np.abs(results["plant.yaw"].to_numpy())
        peaks = [span.max() for span in np.array_split(yaw, 5)]  # 40 s each: > a period
        simulated = math.log(peaks[4] / peaks[1]) / 120.0  # 1/s
        slowest = max(unity_feedback_poles(gain * loop), key=abs)
        assert simulated == pytest.approx(math.log(abs(slowest)) / H, rel=0.25), factor
