"""Sliding-mode heading autopilot (6.3.31)-(6.3.45), sampled: the surface's construction,
the discretised reaching law on the plant itself, and stabilisation of lqr-1's initial
state in the in-process closed loop."""

from __future__ import annotations

import numpy as np
import pytest

from controller_fmu.autopilot import Autopilot, AutopilotConfig
from controller_fmu.lateral_model import CONTROL_STATES, LateralDesignModel
from controller_fmu.matrix_exponential import zero_order_hold
from controller_fmu.sliding_mode import SlidingModeHeading
from cosim.analysis.closed_loop import simulate_closed_loop
from plant_fmu.model.dynamics import STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.stepping import advance

H = 0.01
PSI = CONTROL_STATES.index("yaw")
_IDX = [STATE_INDEX[name] for name in CONTROL_STATES]


@pytest.fixture(scope="module")
def design(remus):
    return LateralDesignModel(remus, 1.525)


def test_surface_is_the_left_eigenvector_of_the_closed_loop_for_the_free_heading(design):
    smc = SlidingModeHeading(design, H)
    Ad, Bd = zero_order_hold(smc.A, smc.B, H)
    closed = Ad - Bd @ smc.k[None, :]
    assert smc.k[PSI] == 0.0  # (6.3.40): psi is left to the sliding surface
    assert smc.w[PSI] == 1.0  # scaled so s is in rad
    np.testing.assert_allclose(smc.w @ closed, smc.w, atol=1e-9)
    others = np.linalg.eigvals(np.delete(np.delete(closed, PSI, 0), PSI, 1))
    assert np.abs(others).max() < 1.0  # the reduced system is stabilised by k


@pytest.mark.parametrize(
    "start",
    [
        {"v": -0.0005},
        {"v": 0.0002, "r": 0.0005, "roll": 0.001},
        {"yaw": 0.01},
    ],
)
def test_one_sampled_step_moves_s_by_the_reaching_law(remus, design, start):
    """s[k+1] - s[k] = -h eta sat(s/Phi) on the nonlinear plant while y_d is unsaturated."""
    smc = SlidingModeHeading(design, H, eta=0.01, boundary_layer=0.001)
    model = PlantModel(remus, variant=Variant.LATERAL)
    x = state_vector({"u": 1.525, **start})
    s0 = smc.sliding_variable(x[_IDX])
    y_d = smc.command(x[_IDX])
    assert abs(y_d) < remus.mass_stroke
    x1 = advance(model, x, input_vector({"mass_position_cmd": y_d}, thrust=9.0), H)
    expected = -H * smc.eta * np.clip(s0 / smc.boundary_layer, -1.0, 1.0)
    assert smc.sliding_variable(x1[_IDX]) - s0 == pytest.approx(expected, rel=0.01)


@pytest.mark.slow
def test_sliding_mode_stabilises_the_lqr1_initial_state(remus):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=2))
    model = PlantModel(remus, variant=Variant.LATERAL)
    run = simulate_closed_loop(autopilot, model, state_vector({"u": 1.5, "v": -0.01}), 60.0, H)
    yaw = np.degrees(run.state("yaw"))
    assert np.abs(yaw[run.times >= 30.0]).max() < 1.0
    final = run.states[-1, _IDX]
    assert abs(autopilot.sliding_mode.sliding_variable(final)) < autopilot.config.smc_boundary_layer
    assert np.abs(run.command("mass_position_cmd")).max() <= 0.06


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [({"eta": 0.0}, "eta = 0.0"), ({"boundary_layer": float("nan")}, "boundary layer = nan")],
)
def test_bad_reaching_parameters_are_refused(design, kwargs, message):
    with pytest.raises(ValueError, match=message):
        SlidingModeHeading(design, H, **kwargs)


@pytest.mark.parametrize(("eta", "layer"), [(100.0, 0.5), (300.0, 0.5), (1.0, 0.005)])
def test_a_reaching_law_unstable_inside_its_boundary_layer_is_refused(design, eta, layer):
    """smc_eta = 300 rad/s (or Phi = 5 mm rad) ran: h eta / Phi >= 2, so inside the layer
    s[k+1] = (1 - h eta / Phi) s[k] grew and the mass command banged between its limits
    (lqr-1's initial state: 5.9 m of command travel in 30 s where the default takes 0.17 m)."""
    with pytest.raises(ValueError, match=rf"eta = {eta!r} rad/s .* h eta / Phi = .*< 2 / h"):
        SlidingModeHeading(design, 0.01, eta=eta, boundary_layer=layer)
    config = AutopilotConfig.build(heading_mode=2, smc_eta=eta, smc_boundary_layer=layer)
    with pytest.raises(ValueError, match=r"expected eta / Phi < 2 / h = 200 1/s"):
        Autopilot(config)
    SlidingModeHeading(design, 0.01, eta=0.99 * 2 * layer / 0.01, boundary_layer=layer)
