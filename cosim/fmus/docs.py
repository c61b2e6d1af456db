"""The documentation page inside each FMU (``documentation/index.html``, FMI 2.0 section 2.1).

The page is generated from the FMU's own ``modelDescription.xml`` (read with fmpy), so it
can never disagree with the variables the FMU declares: what the model is, its default
experiment, one table per causality (inputs, outputs, parameters) with type, unit, start
value, declared range and description (each table captioned, its header cells scoped, in
a box that scrolls sideways on a phone; on paper it wraps to the page), what a host may
and may not do with the FMU (:func:`hosting`: the same for every FMU, and says whether its
binary is the FMU's runtime or pythonfmu's alone), and the references. Only the short "what it
models" paragraph per model identifier is written here by hand (:data:`ABOUT`).

``add_documentation(fmu)`` adds or replaces the page in a built FMU;
``documentation_html(fmu)`` returns it. (pythonfmu's ``build --doc FOLDER`` would copy a
folder written beforehand; generating the page from the finished description needs the
built FMU, so this runs after the build.)
"""

from __future__ import annotations

import html
import os
import zipfile
from pathlib import Path
from typing import Any

DOC_ENTRY = "documentation/index.html"

DISSERTATION = (
    "B. Li, <i>Dynamics and Control of Autonomous Underwater Vehicles with Internal "
    "Actuators</i>, PhD dissertation, Florida Atlantic University, 2016."
)

ABOUT: dict[str, str] = {
    "AuvPlant": (
        "<p>The REMUS&nbsp;100 autonomous underwater vehicle with internal actuators: the "
        "6-DOF rigid body in a (possibly sheared) ocean current, with added mass, "
        "quadratic cross-flow drag and body lift (Ch. 2-4, equations (3.6.2), (4.2.6)-"
        "(4.2.9)), restoring forces (3.5.3), the propeller's thrust and roll torque, the "
        "stern planes, the tunnel thruster, and an internal moving mass on a lateral rail "
        "driven by a servo (Ch. 6). The parameter <code>variant</code> selects the full "
        "6-DOF model, the lateral u-v-r-p-phi-psi model (6.3.13) or the horizontal "
        "u-v-r-psi model (5.1.30). Each communication step is integrated with fixed-step "
        "RK4 (sub-steps no longer than <code>max_substep</code>); the outputs are the state "
        "at the end of the step. The actuator inputs follow the derivatives a master sets "
        "with <code>fmi2SetRealInputDerivatives</code> (u + s u' + s<sup>2</sup>/2 u'' at "
        "each stage's time s into the step), and are held over the step without them; "
        "the currents are always held.</p>"
    ),
    "AuvAutopilot": (
        "<p>The heading and depth autopilot of the REMUS&nbsp;100 with internal actuators "
        "(Ch. 6): an LQR moving-mass servo, a sliding-mode law, or backstepping with the "
        "tunnel thruster (Lyapunov redesign) for the heading; a PD law on the stern planes "
        "for the depth. Its inputs are the plant's outputs of the same names and its "
        "outputs the plant's inputs, so a master can connect same-named variables. The "
        "outputs are computed from the inputs at the start of a communication step and "
        "held over it.</p>"
    ),
    "AuvGuidance": (
        "<p>Waypoint missions for the REMUS&nbsp;100: line-of-sight guidance (Fossen's "
        "lookahead-based steering, or integral LOS against an unknown current) turns the "
        "vehicle's position and a list of waypoints (the <code>waypoints</code> parameter, "
        "<code>north, east, down; ...</code> in metres) into the heading and depth set-points "
        "of the autopilot, with the heading into the current by the crab angle (6.3.74) when "
        "<code>compensate_current</code> is on. It also reports the cross-track error and the "
        "legs completed. Outputs are computed from the inputs at the start of a communication "
        "step and held over it.</p>"
    ),
}

_LOADER = (
    "<li><b>Any FMI host, nothing to set up.</b> The linux64 binary is the FMU's own "
    "runtime (<code>fmu_runtime/native/</code>): it answers every FMI call and runs the "
    "Python code in <code>resources/</code> in the host's Python, or, in a host without "
    "one, in the first usable of: <code>AUV_FMU_PYTHON</code> (a Python executable or a "
    "virtual environment's folder), the Python the FMU was built with, "
    "<code>python3</code> on PATH. It needs CPython&nbsp;3.9 or later with a shared "
    "libpython and numpy (numba is used when present) and glibc&nbsp;2.17 or later. If no "
    "Python can be used, <code>fmi2Instantiate</code> returns NULL and logs one line per "
    "candidate, with the fix.</li>"
    "<li><b>Fallback.</b> <code>AUV_FMU_RUNTIME=pythonfmu</code> runs pythonfmu's own "
    "library instead (<code>&lt;id&gt;_pythonfmu.so</code>, unchanged; it needs "
    "glibc&nbsp;2.32).</li>"
)
_WIN64_PYTHONFMU = (
    "<li><b>Windows.</b> The win64 binary is pythonfmu's (this build had no win64 runtime "
    "made from its C sources; not tested): it runs in the CPython whose "
    "<code>python3.dll</code> Windows finds (the host's own, or one in a folder on PATH), "
    "which must import numpy; it looks for no other Python and refuses input derivatives "
    "(<code>fmi2SetRealInputDerivatives</code>).</li>"
)
_WIN64_RUNTIME = (
    "<li><b>Windows.</b> The win64 binary is the same runtime, cross-compiled "
    "(<code>&lt;id&gt;_pythonfmu.dll</code> beside it is the fallback): it finds a Python "
    "as on Linux, with <code>Scripts\\python.exe</code> in a virtual environment's folder "
    "and <code>python</code> then <code>py -3</code> on PATH; it needs CPython&nbsp;3.9 or "
    "later with numpy. Run under Wine with python.org's CPython&nbsp;3.13 for Windows "
    "(also with fmpy as the host), not on Windows itself.</li>"
)
_NO_LOADER = (
    "<li><b>Python.</b> This FMU was built without a C compiler, so its binary is "
    "pythonfmu's alone: it embeds CPython and runs the Python code in "
    "<code>resources/</code> with numpy from the host process's Python environment. A "
    "non-Python host preloads that environment's <code>libpython</code> and puts its "
    "<code>site-packages</code> on <code>PYTHONPATH</code>; calls against the FMI rules "
    "are refused in Python with an Error logged, but every function but "
    "<code>fmi2DoStep</code> returns fmi2OK (a pythonfmu limit: read the log).</li>"
)
_COMMON = (
    "<li><b>Load, reload, free.</b> Any number of instances, at once or one after "
    "another, from one extraction or a fresh extraction each time; each instance reads "
    "its data from its own extraction. An instance may be freed at any time and its "
    "extraction deleted afterwards. An instantiate/free cycle keeps no memory.</li>"
    "<li><b>Several builds per process.</b> The FMU's Python code lives in a package "
    "named after its content (<code>resources/auvfmu_&lt;hash&gt;</code>): another build "
    "of this FMU in the same process runs its own code, and two extractions of this build "
    "share theirs.</li>"
    "<li><b>FMI 2.0 call sequence.</b> <code>fmi2SetupExperiment</code> and "
    "<code>fmi2EnterInitializationMode</code> once after instantiation, "
    "<code>fmi2ExitInitializationMode</code> once after that, <code>fmi2DoStep</code> from "
    "the start time and each where the previous step ended (to a relative 1e-9), values "
    "within their declared range and finite, fixed parameters only before "
    "initialisation, <code>fmi2Terminate</code> once initialised. Anything else is refused "
    "with an Error logged and changes nothing; the call returns fmi2Error, and the "
    "instance may go on with valid calls. A failed initialisation leaves the instance in "
    "the error state; a step the model cannot take returns fmi2Discard and may be "
    'repeated. Outputs declared <code>initial="calculated"</code> depend on parameters: '
    "read in initialisation mode, they give the values the FMU will start from.</li>"
    "<li><b>Process exit.</b> A host may exit without terminating or freeing its "
    "instances.</li>"
)


def hosting(with_loader: bool, win64_runtime: bool = False) -> str:
    """The "what a host may and may not do" section, for a linux64 binary with or without
    the FMU's runtime, and a win64 binary that is the runtime or pythonfmu's."""
    return (
        "<h2>What a host may and may not do</h2><ul>"
        + (_LOADER if with_loader else _NO_LOADER)
        + (_WIN64_RUNTIME if win64_runtime else _WIN64_PYTHONFMU)
        + _COMMON
        + "</ul>"
    )


_SECTIONS = (
    ("Inputs", ("input",)),
    ("Outputs", ("output",)),
    ("Parameters", ("parameter", "calculatedParameter")),
    ("Other variables", ("local", "independent")),
)

_STYLE = (
    "body{font-family:sans-serif;max-width:60em;margin:2em auto;line-height:1.4}"
    "table{border-collapse:collapse;width:100%}"
    "th,td{border:1px solid #bbb;padding:.2em .5em;text-align:left;vertical-align:top}"
    "th{background:#eee}code{font-size:95%}caption{text-align:left;font-weight:bold}"
    ".wide{overflow-x:auto}"  # a table wider than a phone scrolls in its box, not the page
    "@media print{.wide{overflow:visible}th,td{overflow-wrap:anywhere}}"  # wraps on paper
)


def documentation_html(fmu: str | os.PathLike[str]) -> str:
    """The documentation page of ``fmu`` (an .fmu file or a modelDescription.xml)."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu), validate=False)
    name = md.coSimulation.modelIdentifier if md.coSimulation else md.modelName
    e = html.escape
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{e(name)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{e(name)}</h1>",
        f"<p><b>{e(md.description or '')}</b></p>",
        ABOUT.get(name, ""),
        _facts(md),
    ]
    for title, causalities in _SECTIONS:
        variables = [v for v in md.modelVariables if v.causality in causalities]
        if variables:
            parts.append(f"<h2>{title} ({len(variables)})</h2>")
            parts.append(_table(variables, f"{title} of {name}"))
    parts += [
        hosting(_has_loader(fmu), _has_loader(fmu, "win64")),
        "<h2>References</h2><ul>",
        f"<li>{DISSERTATION} Equation and table numbers above refer to it.</li>",
        "<li>Functional Mock-up Interface 2.0 for Model Exchange and Co-Simulation, "
        "Modelica Association.</li>",
        "</ul></body></html>",
    ]
    return "\n".join(part for part in parts if part) + "\n"


def _has_loader(fmu: str | os.PathLike[str], platform: str = "linux64") -> bool:
    """True if ``fmu`` is an FMU file whose ``platform`` binary is the FMU's runtime."""
    if not zipfile.is_zipfile(fmu):
        return False
    wrapper = f"binaries/{platform}/"
    suffix = "_pythonfmu.so" if platform == "linux64" else "_pythonfmu.dll"
    with zipfile.ZipFile(fmu) as archive:
        return any(n.startswith(wrapper) and n.endswith(suffix) for n in archive.namelist())


def _facts(md: Any) -> str:
    e = html.escape
    rows = [
        ("FMI version", f"{md.fmiVersion}, co-simulation"),
        ("Generated by", md.generationTool or ""),
        ("GUID", md.guid),
    ]
    experiment = md.defaultExperiment
    if experiment is not None:
        rows.append(
            (
                "Default experiment",
                f"start {experiment.startTime} s, stop {experiment.stopTime} s, "
                f"communication step {experiment.stepSize} s",
            )
        )
    facts = "".join(f'<tr><th scope="row">{e(k)}</th><td>{e(v)}</td></tr>' for k, v in rows)
    return _boxed("The FMU", facts)


def _boxed(caption: str, rows: str) -> str:
    """A table of ``rows`` with its ``caption``, in a box that scrolls sideways when the
    table is wider than the window (a phone's), reached by the keyboard and named for a
    screen reader; in print the table wraps to the page instead (:data:`_STYLE`)."""
    e = html.escape
    return (
        f'<div class="wide" role="region" aria-label="{e(caption)}" tabindex="0">'
        f"<table><caption>{e(caption)}</caption>{rows}</table></div>"
    )


def _table(variables: list[Any], caption: str) -> str:
    """The variables' table, a row each, under ``caption``."""
    e = html.escape
    columns = ("name", "type", "unit", "start", "range", "variability", "description")
    head = "<tr>" + "".join(f'<th scope="col">{c}</th>' for c in columns) + "</tr>"
    rows = []
    for v in variables:
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None) or ""
        start = "" if v.start is None else str(v.start)
        rows.append(
            f"<tr><td><code>{e(v.name)}</code></td><td>{e(v.type)}</td><td>{e(unit)}</td>"
            f"<td>{e(start)}</td><td>{e(value_range(v))}</td><td>{e(v.variability or '')}</td>"
            f"<td>{e(v.description or '')}</td></tr>"
        )
    return _boxed(caption, head + "".join(rows))


def value_range(variable: Any) -> str:
    """The declared range of a variable as the page shows it: ``0 .. 2``, ``>= 0.0``,
    ``<= 1``, or empty."""
    low, high = variable.min, variable.max
    if low is not None and high is not None:
        return f"{low} .. {high}"
    if low is not None:
        return f">= {low}"
    return "" if high is None else f"<= {high}"


def add_documentation(fmu: str | os.PathLike[str]) -> None:
    """Add (or replace) ``documentation/index.html`` in the FMU file ``fmu``, in place."""
    fmu = Path(fmu)
    page = documentation_html(fmu).encode("utf-8")
    with zipfile.ZipFile(fmu) as archive:
        entries = [(info, archive.read(info)) for info in archive.infolist()]
    partial = fmu.with_name(f".{fmu.name}.doc.tmp")
    try:
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for info, data in entries:
                if info.filename != DOC_ENTRY:
                    archive.writestr(info, data)
            info = zipfile.ZipInfo(DOC_ENTRY, date_time=entries[0][0].date_time)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            archive.writestr(info, page)
        os.replace(partial, fmu)
    finally:
        partial.unlink(missing_ok=True)
