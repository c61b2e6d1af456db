"""Regenerate ``docs/interfaces.md``: the variables of our FMUs, from their model descriptions.

    python scripts/interfaces_doc.py [--fmu-dir build/fmus] [--out docs/interfaces.md] [--check]

The FMUs in ``--fmu-dir`` are built first if missing or out of date. The tables (name,
type, unit, start, range, variability, description per causality) are read from each FMU's
``modelDescription.xml`` with fmpy, so the page cannot disagree with what the FMUs
declare; only the contract around them (:data:`CONTRACT`) is written here. ``--check``
writes nothing and exits 1 if the page is not what this script would write.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from fmpy import read_model_description

from cosim.errors import CosimError
from cosim.fmus.build import FMUS, ensure_fmus
from cosim.fmus.docs import value_range

ROOT = Path(__file__).resolve().parents[1]

CONTRACT = """\
# The FMUs' interface

Generated from the built FMUs' `modelDescription.xml` by
`python scripts/interfaces_doc.py`; do not edit by hand (the tests check it is current).

`AuvPlant.fmu` (the vehicle in the water, [the model](model.md)), `AuvAutopilot.fmu`
(its heading and depth controllers) and `AuvGuidance.fmu` (waypoint missions,
[manoeuvres.md](manoeuvres.md)) are FMI 2.0 co-simulation FMUs. What users, other FMI
tools and our own checks may rely on:

- **Names connect them.** The autopilot's inputs carry the names of the plant outputs
  they measure (`yaw`, `r`, `p`, `roll`, `v_rel`, ...) plus the set-points `yaw_setpoint`
  and `depth_setpoint` and the measured current; its outputs carry the names of the plant
  inputs they drive (`mass_position_cmd`, `tunnel_force`, `fin_angle`, `thrust`). A
  master connects same-named variables by default. The guidance reads the plant's
  `north`, `east` and `yaw` and feeds the autopilot's `yaw_setpoint` and
  `depth_setpoint`. In results, recordings and exported SSP/OSP files the built-in
  scenarios name the instances `plant`, `controller` and `guidance`, and a column is named
  `<instance>.<variable>` (see the README's "What a run writes"). A scenario of several
  vehicles names each plant and autopilot its own way (`plant_a`, `ctrl_a`); the
  recording's 3-D scene and plots, the report and a study's overlay then draw each vehicle
  under its plant's name (`world/plant_a/vehicle`, `vehicles/plant_a/attitude/yaw_deg`,
  `velocities_plant_a.png`; one vehicle keeps `world/vehicle`, `attitude/yaw_deg` and
  `velocities.png`:
  [runs.md](runs.md#two-or-more-vehicles-in-one-scenario)).
- **Units**: SI, angles in radians, declared on every Real variable (with the unit
  definitions in `modelDescription.xml`); every variable has a description.
- **Model structure**: `needsExecutionTool="false"`; every output is listed with its
  dependencies (none of ours depends directly on an input: each is computed at
  initialisation or at the end of a step), so importers see no algebraic loop between
  plant and controller; every output is `initial="calculated"` (no start in the tables
  below: the FMU computes it, so no host sets it; read in initialisation mode, it gives
  the value the FMU starts from); a default experiment.
- **Behaviour**: the same inputs give bit-identical outputs; `fmi2GetFMUstate` /
  `fmi2SetFMUstate` save and restore the whole state, and a restored run continues
  exactly as the original; `fmi2SerializeFMUstate` / `fmi2DeSerializeFMUstate` turn it
  into bytes and back (`canSerializeFMUstate="true"`), which `auv-cosim run
  --checkpoint-every` keeps in a run's `checkpoint.json` and `--resume` gives back
  ([runs.md](runs.md#a-killed-run-resumed)); bad input (NaN, a value out of range, a fixed parameter
  written after initialisation) is refused with a logged reason, and a failure comes back
  as fmi2Error or fmi2Discard, never as a crash of the host (see
  [fmi-notes.md](fmi-notes.md) for why that takes care with pythonfmu).
- **Ranges**: every bounded Integer and Real parameter declares `min`/`max` (the range
  column below); a value outside is refused, naming the variable.
- **Log categories**: each declares pythonfmu's five, `logStatusWarning`,
  `logStatusDiscard`, `logStatusError`, `logStatusFatal` and `logAll`, and its own debug
  categories: AuvPlant `logPlantSteps` (the RK4 sub-step count and the path, compiled or
  numpy reference, when they change), AuvAutopilot `logAutopilotLimits` (a command,
  `mass_position_cmd`, `tunnel_force` or `fin_angle`, reaching or leaving its limit) and
  `logAutopilotTuning` (tunable parameters changed during a run, as the law takes them);
  `fmi2SetDebugLogging` takes those and refuses another with fmi2Error, naming them.
  Warnings and worse reach the host's logger whatever debug logging is set to, debug
  (fmi2OK) messages of a category only while it is on for that category, for `logAll` or
  for every category (none named); a message of a category that is off is never
  formatted. In a scenario, an instance's `debug_logging = true` or `log_categories =
  [...]`, or `auv-cosim run --fmu-log INSTANCE[:CATEGORY,...]` (`auv-cosim sweep
  --fmu-log` for every run of a study), turns it on and shows the messages
  ([runs.md](runs.md#an-fmus-debug-log)).
- **Hosts**: they load, validate and run in fmpy, OSP's libcosim (libcosimpy) and ecos
  (ecospy), alone and connected, with the results of our own master under the same
  coupling; the README's "Use the FMUs in other tools" shows how. A host may load, reload
  and free them as often as it likes, from fresh extractions too, several builds in one
  process, in the FMI 2.0 call sequence (docs/hosts.md, "What a host needs").
"""

SECTIONS = (
    ("Inputs", ("input",)),
    ("Outputs", ("output",)),
    ("Parameters", ("parameter", "calculatedParameter")),
    ("Other variables", ("local", "independent")),
)


def render(fmus: dict[str, Path]) -> str:
    """The page for the FMUs ``{model identifier: path}``, in :data:`FMUS` order."""
    parts = [CONTRACT]
    for name in FMUS:
        parts.append(_fmu_section(name, read_model_description(str(fmus[name]), validate=False)))
    return "\n".join(parts)


def _fmu_section(name: str, md: Any) -> str:
    lines = [f"## {name}", ""]
    if md.description:
        lines += [md.description, ""]
    experiment = md.defaultExperiment
    facts = f"FMI {md.fmiVersion} co-simulation, modelIdentifier `{name}`"
    if experiment is not None:
        facts += (
            f"; default experiment: {experiment.startTime} s to {experiment.stopTime} s, "
            f"communication step {experiment.stepSize} s"
        )
    lines += [facts + ".", ""]
    for title, causalities in SECTIONS:
        variables = [v for v in md.modelVariables if v.causality in causalities]
        if variables:
            lines += [f"### {name}: {title.lower()}", "", *_table(variables), ""]
    return "\n".join(lines)


def _table(variables: list[Any]) -> list[str]:
    rows = [
        "| name | type | unit | start | range | variability | description |",
        "|---|---|---|---|---|---|---|",
    ]
    for v in variables:
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None) or ""
        start = "" if v.start is None else str(v.start)
        cells = (f"`{v.name}`", v.type, unit, start, value_range(v), v.variability or "",
                 v.description or "")  # fmt: skip
        rows.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return rows


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--fmu-dir", type=Path, default=ROOT / "build" / "fmus", help="[build/fmus]"
    )
    parser.add_argument(
        "--out", type=Path, default=ROOT / "docs" / "interfaces.md", help="[docs/interfaces.md]"
    )
    parser.add_argument("--check", action="store_true", help="exit 1 if --out is not current")
    args = parser.parse_args(argv)
    try:
        page = render(ensure_fmus(args.fmu_dir))
    except CosimError as exc:
        print(f"interfaces_doc: {exc}", file=sys.stderr)
        return 2
    if args.check:
        current = args.out.read_text(encoding="utf-8") if args.out.is_file() else ""
        if current != page:
            print(
                f"{args.out} is out of date: run python scripts/interfaces_doc.py", file=sys.stderr
            )
            return 1
        return 0
    args.out.write_text(page, encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
