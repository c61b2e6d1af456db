"""``auv-cosim analyze``: equilibria, continuation sweeps and phase portraits.

The command-line side of :mod:`cosim.analysis.bifurcation`: builds the operating conditions
from the options, prints tables or JSON, writes CSV files and the figures of
:mod:`cosim.analysis.plots`. The physics all comes from the plant's own model.

* ``equilibria``: every equilibrium in the search box with its Jacobian eigenvalues and
  stability (``--json``: a list of ``{"state": {name: value}, "eigenvalues": [[re, im],
  ...], "stable": bool, "units": {"state": {name: unit}, "eigenvalues": "1/s"}}``, SI).
* ``sweep PARAM FROM TO``: ``<out>/sweep_<PARAM>.png`` (bifurcation diagram),
  ``<out>/sweep_<PARAM>.csv`` (the branches) and ``<out>/sweep_<PARAM>_special_points.csv``
  (folds, branch points, Hopf points), with a progress bar. Every CSV column but ``branch``,
  ``kind`` and ``stable`` (0/1) names its SI unit in its header: ``u [m/s]``, ``mu [1]``.
  A sweep replaces an earlier sweep of the same parameter in ``<out>``, and says so.
* ``phase-portrait``: ``<out>/phase_portrait.png``, open-loop trajectories from a grid of
  initial states in the search box (Figs. 5.4-5.5).
"""

from __future__ import annotations

import csv
import json
import math
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from cosim.analysis.bifurcation import (
    Q_PROP,
    SEARCH_BOX,
    AnalysisError,
    OperatingConditions,
    Sweep,
    cg_offset,
    check_conditions,
    check_sweep,
    find_equilibria,
    sweep,
)
from cosim.analysis.equilibria import Equilibrium
from cosim.errors import FLAGS, CosimError, unmade_folder
from cosim.whole_file import write_whole
from plant_fmu.model.dynamics import STATE_INDEX, STATE_NAMES, STATE_UNITS, Variant
from plant_fmu.model.parameters import VehicleParameterError, load_vehicle
from plant_fmu.model.stepping import simulate

# Phase portraits: how long each open-loop trajectory runs and its RK4 step. The slowest
# open-loop mode of the REMUS (surge, 2 alpha U0 = -0.38 1/s) has decayed to 1e-5 in 30 s;
# the fastest (-6.5 1/s, Example 5.1's stable points) gives lambda h = 0.33 at h = 0.05 s.
PHASE_DURATION_S = 30.0
PHASE_STEP_S = 0.05
# Initial states: u on these values, (v, r) on the corners, edge midpoints and centre of
# the box |v|, |r| <= 0.4, plus two starts along the unstable direction of each unstable
# equilibrium (they trace its unstable manifold, as Fig. 5.4 shows).
PHASE_U0 = (0.3, 1.0, 1.9)
PHASE_VR0 = tuple((v, r) for v in (-0.4, 0.0, 0.4) for r in (-0.4, 0.0, 0.4))
MANIFOLD_OFFSET = 0.01
ZERO_BELOW = 1e-12  # a printed state below this times its unit's largest in the table: 0
PHASE_PORTRAIT = "phase_portrait.png"


def _flag(name: str, value: float, unit: str) -> str:
    """A condition as the command line's flag gives it, ``--thrust -1.0`` (the flag's help
    gives its SI unit, so ``unit`` is not repeated)."""
    return FLAGS.given(name, value)


def operating_conditions(
    vehicle: str,
    variant: int | None,
    thrust: float,
    roll_torque: float,
    mass_position: float,
    current_east: float,
    sweep_parameter: str | None = None,
) -> OperatingConditions:
    """The operating conditions an analysis runs at (SI: N, N.m, m, m/s).

    ``variant`` None picks what the analysis needs: roll torque and the moving mass act
    through roll, so their sweeps (``sweep_parameter``) need the lateral model (Sec.
    5.1.3-5.1.4); the rest are the horizontal analyses of Sec. 5.1.2.
    """
    if variant is not None:
        chosen = Variant(variant)
    elif sweep_parameter in ("roll_torque", "mass_position"):
        chosen = Variant.LATERAL
    else:
        chosen = Variant.HORIZONTAL
    try:
        params = load_vehicle(vehicle)
    except VehicleParameterError as exc:
        raise AnalysisError(str(exc)) from None
    # named as the command line gives them, before OperatingConditions names its fields
    check_conditions(params, chosen, thrust, roll_torque, mass_position, current_east, _flag)
    return OperatingConditions(
        params=params,
        variant=chosen,
        thrust=thrust,
        roll_torque=roll_torque,
        mass_position=mass_position,
        current_east=current_east,
    )


def describe(conditions: OperatingConditions, swept: str | None = None) -> str:
    """One line naming the vehicle, variant and inputs; the ``swept`` parameter (a sweep's)
    is named as swept, not with the fixed value it does not keep."""
    inputs = {
        "roll_torque": f"roll torque {conditions.roll_torque:g} N.m",
        "mass_position": f"mass position {conditions.mass_position:g} m",
    }
    if swept is not None:
        inputs[swept] = f"{swept.replace('_', ' ')} swept"
    return (
        f"vehicle {conditions.params.name}, variant {int(conditions.variant)} "
        f"({conditions.variant.name.lower()}), thrust {conditions.thrust:g} N, "
        f"{', '.join(inputs.values())}, current east {conditions.current_east:g} m/s"
    )


# --- equilibria ----------------------------------------------------------------------------


def equilibrium_record(eq: Equilibrium) -> dict:
    """The JSON object of one equilibrium: full state by name, eigenvalues, stability, and
    the SI unit of each (``units``: the state's by name, the eigenvalues' 1/s)."""
    return {
        "state": {name: float(value) for name, value in zip(STATE_NAMES, eq.state, strict=True)},
        "eigenvalues": [[float(z.real), float(z.imag)] for z in _ordered(eq.eigenvalues)],
        "stable": eq.stable,
        "units": {"state": dict(zip(STATE_NAMES, STATE_UNITS, strict=True)), "eigenvalues": "1/s"},
    }


def _ordered(eigenvalues: np.ndarray) -> np.ndarray:
    """Eigenvalues sorted by real part then imaginary part (deterministic output)."""
    return np.array(sorted(eigenvalues, key=lambda z: (round(z.real, 12), z.imag)))


def print_equilibria(conditions: OperatingConditions, as_json: bool) -> int:
    """``auv-cosim analyze equilibria``: print the table (or JSON); 0 on success."""
    equilibria = find_equilibria(conditions)
    if as_json:
        print(json.dumps([equilibrium_record(eq) for eq in equilibria], indent=2))
        return 0
    print(describe(conditions))
    print(equilibria_table(conditions, equilibria))
    return 0


def equilibria_table(conditions: OperatingConditions, equilibria: Sequence[Equilibrium]) -> str:
    """A plain-text table: one row per equilibrium, its free states, stability, eigenvalues."""
    names = conditions.free_states
    box = search_box_text(names)
    lines = [f"{len(equilibria)} equilibri{'um' if len(equilibria) == 1 else 'a'} in {box}:"]
    header = [f"{n} [{STATE_UNITS[STATE_INDEX[n]]}]" for n in names]
    lines.append("  ".join(f"{h:>14}" for h in header) + "  stable    eigenvalues [1/s]")
    states = numerical_zeros([{n: eq.value(n) for n in names} for eq in equilibria])
    for eq, state in zip(equilibria, states, strict=True):
        values = "  ".join(f"{state[n]:>14.6g}" for n in names)
        eigen = ", ".join(_complex(z) for z in _ordered(eq.eigenvalues))
        lines.append(f"{values}  {'yes' if eq.stable else 'no':<8}  {eigen}")
    if conditions.current_east != 0.0:
        lines.append(
            "(with a current: equilibria of the motion relative to the water, (5.2.10); "
            "velocities over ground while heading north)"
        )
    return "\n".join(lines)


def search_box_text(names: Sequence[str]) -> str:
    """The search box over these free states, with units, e.g.
    '0 < u < 2 m/s, |v| <= 0.4 m/s, |p|, |r| <= 0.4 rad/s, |roll| < 90 deg'."""
    low, high = SEARCH_BOX["u"]
    parts = [f"{low:g} < u < {high:g} m/s"]
    rates = [n for n in names if n != "u" and n in SEARCH_BOX and n not in ("roll", "pitch")]
    for unit in dict.fromkeys(_unit(n) for n in rates):
        same = [n for n in rates if _unit(n) == unit]
        bound = SEARCH_BOX[same[0]][1]
        parts.append(", ".join(f"|{n}|" for n in same) + f" <= {bound:g} {unit}")
    angles = [n for n in names if n in ("roll", "pitch")]
    if angles:
        parts.append(", ".join(f"|{n}|" for n in angles) + " < 90 deg")
    return ", ".join(parts)


def numerical_zeros(rows: Sequence[Mapping[str, float]]) -> list[dict[str, float]]:
    """The rows of state values (SI units) with each numerical zero printed as 0: a value
    below :data:`ZERO_BELOW` times the largest |value| of its unit over the rows (a roll
    rate of -6.8e-31 rad/s beside a yaw rate of 0.14 rad/s, as the solver leaves it), or
    than the search box's largest bound of that unit (2 m/s, 0.4 rad/s, pi/2 rad), so that
    a unit whose values are all noise (the straight line's branch point over mu: roll,
    p and r ~1e-22 and less) is printed as 0 too."""
    scale: dict[str, float] = {}
    for name, bounds in SEARCH_BOX.items():
        scale[_unit(name)] = max(scale.get(_unit(name), 0.0), *map(abs, bounds))
    for row in rows:
        for name, value in row.items():
            scale[_unit(name)] = max(scale.get(_unit(name), 0.0), abs(value))
    return [
        {n: 0.0 if abs(v) < ZERO_BELOW * scale[_unit(n)] else v for n, v in row.items()}
        for row in rows
    ]


def _unit(name: str) -> str:
    return STATE_UNITS[STATE_INDEX[name]]


def _complex(z: complex) -> str:
    return f"{z.real:.4g}" if abs(z.imag) < 1e-12 else f"{z.real:.4g}{z.imag:+.4g}i"


# --- sweep ---------------------------------------------------------------------------------

SWEEP_UNITS = {"roll_torque": " N.m", "mass_position": " m", "mu": "", "eta": ""}
"""The unit of each sweep parameter as printed after a value (the factors have none)."""
PARAMETER_UNITS = {"roll_torque": "N.m", "mass_position": "m", "mu": "1", "eta": "1"}
"""The SI unit of each sweep parameter in a CSV header ("1": the factors' dimensionless)."""


def sweep_command(
    conditions: OperatingConditions,
    parameter: str,
    start: float,
    stop: float,
    steps: int,
    out: Path,
) -> int:
    """``auv-cosim analyze sweep``: write the sweep's files, print its special points and
    the files, saying which replaced an earlier analysis's."""
    earlier = {path for path in sweep_paths(out, parameter).values() if path.exists()}
    result, paths = run_sweep(
        conditions, parameter, start, stop, steps, out, names=("FROM", "TO", "--steps")
    )
    print(describe(conditions, swept=parameter))
    print(special_points_table(result, conditions))
    for name, path in paths.items():
        print(f"  {name:<15} {_written(path, earlier)}")
    return 0


def sweep_paths(out: Path, parameter: str) -> dict[str, Path]:
    """The files a sweep of ``parameter`` writes into ``out``, by name."""
    stem = f"sweep_{parameter}"
    return {
        "figure": out / f"{stem}.png",
        "branches": out / f"{stem}.csv",
        "special_points": out / f"{stem}_special_points.csv",
    }


def _written(path: Path, earlier: set[Path]) -> str:
    """``path`` as the command lists it, saying so when it replaced an earlier file."""
    return f"{path} (replaced the earlier one)" if path in earlier else str(path)


def run_sweep(
    conditions: OperatingConditions,
    parameter: str,
    start: float,
    stop: float,
    steps: int,
    out: Path,
    seeds: dict | None = None,
    names: tuple[str, str, str] = ("start", "stop", "steps ="),
) -> tuple[Sweep, dict[str, Path]]:
    """Continue the branches with a progress bar and write the figure and CSV files.

    The arguments are checked before ``out`` is made (``names`` name ``start``, ``stop``
    and ``steps`` in a refusal). Returns the :class:`Sweep` and the paths by name (``figure``,
    ``branches``, ``special_points``).
    """
    from cosim.analysis.plots import plot_sweep

    check_sweep(conditions, parameter, start, stop, steps, names=names)
    _output_folder(out, "the sweep outputs")
    with tqdm(desc=f"sweep {parameter}", unit="step", disable=None, leave=False) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        result = sweep(conditions, parameter, start, stop, steps, seeds=seeds, progress=progress)
    paths = sweep_paths(out, parameter)
    try:
        write_branches_csv(result, conditions, paths["branches"])
        write_special_points_csv(result, paths["special_points"])
        setting = describe(conditions, swept=parameter)
        title = f"{conditions.params.name}: equilibria over {parameter} ({setting})"
        plot_sweep(result, conditions.params, paths["figure"], title=title)
    except OSError as exc:
        raise CosimError(f"cannot write the sweep outputs to {out}: {_unwritten(exc)}") from None
    return result, paths


def write_branches_csv(result: Sweep, conditions: OperatingConditions, path: Path) -> Path:
    """One row per branch point: branch, parameter, (y_g,) free states, stable, the largest
    eigenvalue real part."""
    with_cg = result.parameter == "mass_position"
    write_whole(path, lambda tmp: _write_branches(result, conditions, with_cg, tmp))
    return path


def _write_branches(
    result: Sweep, conditions: OperatingConditions, with_cg: bool, path: Path
) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(
            [
                "branch",
                _parameter_header(result.parameter),
                *(["cg_offset_y_g [m]"] if with_cg else []),
                *_state_headers(result.free_states),
                "stable",
                "max_real_eigenvalue [1/s]",
            ]
        )
        for b, branch in enumerate(result.branches):
            for k, value in enumerate(branch.parameters):
                extra = [repr(cg_offset(conditions.params, float(value)))] if with_cg else []
                writer.writerow(
                    [b, repr(float(value)), *extra]
                    + [repr(float(z)) for z in branch.states[k]]
                    + [int(branch.stable[k]), repr(float(branch.eigenvalues[k].real.max()))]
                )


def write_special_points_csv(result: Sweep, path: Path) -> Path:
    """One row per special point (fold, Hopf, ...): kind, branch, parameter, free states."""
    write_whole(path, lambda tmp: _write_special_points(result, tmp))
    return path


def _write_special_points(result: Sweep, path: Path) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        header = [_parameter_header(result.parameter), *_state_headers(result.free_states)]
        writer.writerow(["kind", "branch", *header])
        for s in result.special_points:
            writer.writerow(
                [s.kind, s.branch, repr(s.parameter)]
                + [repr(s.state[n]) for n in result.free_states]
            )


def _parameter_header(parameter: str) -> str:
    """A CSV column of the swept parameter with its unit, e.g. 'roll_torque [N.m]'."""
    return f"{parameter} [{PARAMETER_UNITS[parameter]}]"


def _state_headers(names: Sequence[str]) -> list[str]:
    """CSV columns of these states with their SI units, e.g. 'roll [rad]', 'u [m/s]'."""
    return [f"{n} [{_unit(n)}]" for n in names]


def _unwritten(exc: OSError) -> str:
    """'FILE: why' for an output file that could not be written (a full disk)."""
    why = exc.strerror or str(exc)
    return f"{exc.filename}: {why}" if exc.filename else why


def special_points_table(result: Sweep, conditions: OperatingConditions) -> str:
    """Human-readable list of the special points, in the dissertation's units."""
    unit = SWEEP_UNITS[result.parameter]
    lines = [
        f"{len(result.branches)} branch(es) over {result.parameter} from {result.start:g}{unit} "
        f"to {result.stop:g}{unit}; {len(result.special_points)} special point(s):"
    ]
    states = numerical_zeros([s.state for s in result.special_points])
    for s, values in zip(result.special_points, states, strict=True):
        where = f"{result.parameter} = {s.parameter:.6g}{unit}"
        if result.parameter == "roll_torque":
            where += f" ({s.parameter / Q_PROP:.4g} Q_prop)"
        elif result.parameter == "mass_position":
            where += f" (y_g = {100 * cg_offset(conditions.params, s.parameter):.4g} cm)"
        state = ", ".join(
            f"{n} = {math.degrees(v):.4g} deg"
            if n in ("roll", "pitch")
            else f"{n} = {v:.4g} {_unit(n)}"
            for n, v in values.items()
        )
        lines.append(f"  {s.kind:<12} at {where}: {state}")
    return "\n".join(lines)


# --- phase portrait ------------------------------------------------------------------------


def phase_trajectories(
    conditions: OperatingConditions,
    equilibria: Sequence[Equilibrium],
    duration: float = PHASE_DURATION_S,
    step: float = PHASE_STEP_S,
) -> list[np.ndarray]:
    """Open-loop state histories (``STATE_NAMES`` columns) from the grid of initial
    states and along the unstable direction of every unstable equilibrium."""
    starts = [conditions.state({"u": u, "v": v, "r": r}) for u in PHASE_U0 for v, r in PHASE_VR0]
    for eq in equilibria:
        if eq.stable:
            continue
        values, vectors = np.linalg.eig(eq.jacobian)
        direction = vectors[:, int(np.argmax(values.real))].real
        idx = [STATE_INDEX[n] for n in eq.free_states]
        for sign in (-1.0, 1.0):
            x0 = eq.state.copy()
            x0[idx] += sign * MANIFOLD_OFFSET * direction / np.linalg.norm(direction)
            starts.append(x0)
    model, inputs = conditions.model, conditions.inputs()
    histories = []
    bar = tqdm(starts, desc="phase portrait", unit="trajectory", disable=None, leave=False)
    for x0 in bar:
        try:
            _, states = simulate(model, x0, inputs, duration, step, max_substep=step)
        except ValueError:
            continue  # a start the model cannot integrate (left its range): skip it
        histories.append(states)
    return histories


def _output_folder(out: Path, what: str) -> None:
    """Make ``out`` (and its parents) and write a file there, removed at once, before the
    minutes of work that fill it; raises CosimError naming it and ``--out`` when it cannot
    be made (a file of that name, no permission) or written (a read-only working folder's
    ``analysis/``, which an earlier run made)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        why = unmade_folder(out, exc)
    else:
        try:
            tempfile.TemporaryFile(dir=out).close()
            return
        except OSError as exc:
            why = exc.strerror or str(exc)
    raise CosimError(f"cannot write {what} to {out}: {why}; name a folder you can write with --out")


def phase_portrait_command(conditions: OperatingConditions, out: Path) -> int:
    """``auv-cosim analyze phase-portrait``: write the figure, print the equilibria."""
    from cosim.analysis.plots import plot_phase_portrait

    if conditions.current_east != 0.0:
        raise CosimError(
            f"--current-east {conditions.current_east:g}: the phase portrait is of the motion "
            "in still water (Figs. 5.4-5.5); drop the current"
        )
    _output_folder(out, "the phase portrait")
    earlier = {out / PHASE_PORTRAIT} if (out / PHASE_PORTRAIT).exists() else set()
    with tqdm(desc="phase portrait: finding the equilibria", total=None, disable=None,
              leave=False, bar_format="{desc} [{elapsed}]"):  # fmt: skip
        equilibria = find_equilibria(conditions)
    trajectories = phase_trajectories(conditions, equilibria)
    title = f"open-loop phase portrait: {describe(conditions)}"
    try:
        path = plot_phase_portrait(trajectories, equilibria, out / PHASE_PORTRAIT, title)
    except OSError as exc:
        raise CosimError(f"cannot write the phase portrait to {out}: {_unwritten(exc)}") from None
    print(describe(conditions))
    print(equilibria_table(conditions, equilibria))
    print(
        f"  {len(trajectories)} trajectories of {PHASE_DURATION_S:g} s: {_written(path, earlier)}"
    )
    return 0
