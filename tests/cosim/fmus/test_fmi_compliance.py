"""The built FMUs and an exported SSP against the FMI 2.0 and SSP 1.0 standards: what a
tool vendor importing them checks.

The schemas come with fmpy (``fmpy/schema/fmi2``, ``fmpy/ssp/schema``); the rules of the
standards' text that no schema checks are checked here one by one: the allowed
causality/variability/initial combinations (FMI 2.0, section 2.2.7), where a ``start``
is required and where it is forbidden, ``ModelStructure`` (section 2.2.8, with the
dependencies measured by perturbing every known in initialisation mode), the units'
SI base-unit exponents (checked against the unit's name, independently of the build),
display units, the naming convention, which variables a host may set before
initialisation (section 4.2.4), the documentation page, and the SSD's connectors and
parameter values against the FMUs they package.
"""

from __future__ import annotations

import io
import json
import math
import re
import zipfile
from pathlib import Path
from typing import Any

import fmpy
import pytest
from fmpy import read_model_description
from lxml import etree

from cosim.export import export_ssp
from cosim.fmus.build import FMUS
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import load_scenario, scenario_from_toml

FMI2_SCHEMA = Path(fmpy.__file__).parent / "schema" / "fmi2" / "fmi2ModelDescription.xsd"
SSD_SCHEMA = Path(fmpy.__file__).parent / "ssp" / "schema" / "SystemStructureDescription.xsd"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
}

# FMI 2.0, section 2.2.7: the initial values each (causality, variability) allows; the
# first is the default. A combination not listed is not allowed.
_A, _B, _C, _D = ("exact",), ("calculated", "approx"), ("calculated", "exact", "approx"), (None,)
ALLOWED_INITIAL: dict[tuple[str, str], tuple[str | None, ...]] = {
    ("output", "constant"): _A,
    ("local", "constant"): _A,
    ("parameter", "fixed"): _A,
    ("parameter", "tunable"): _A,
    ("calculatedParameter", "fixed"): _B,
    ("calculatedParameter", "tunable"): _B,
    ("local", "fixed"): _B,
    ("local", "tunable"): _B,
    ("input", "discrete"): _D,
    ("input", "continuous"): _D,
    ("output", "discrete"): _C,
    ("output", "continuous"): _C,
    ("local", "discrete"): _C,
    ("local", "continuous"): _C,
    ("independent", "continuous"): _D,
}

# SI base-unit exponents of the symbols a unit name is made of (kept apart from the build's
# own table: this checks that table)
SI_SYMBOLS: dict[str, dict[str, int]] = {
    "1": {},
    "m": {"m": 1},
    "kg": {"kg": 1},
    "s": {"s": 1},
    "rad": {"rad": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "J": {"kg": 1, "m": 2, "s": -2},
    "W": {"kg": 1, "m": 2, "s": -3},
}
DEGREE = math.radians(1.0)  # rad: 1 deg; a display value in deg is the value in rad / DEGREE
# FMI 2.0, section 2.2.9: a structured name is identifiers (or quoted names) joined by
# dots, each with an optional array index; ours are plain identifiers
STRUCTURED_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\[\d+(,\d+)*\])?(\.[A-Za-z_]\w*(\[\d+\])?)*")


def _root(fmu: Path) -> Any:
    with zipfile.ZipFile(fmu) as archive:
        return etree.fromstring(archive.read("modelDescription.xml"))


def _initial(var: Any) -> str | None:
    """A ScalarVariable's initial, the standard's default where it declares none."""
    causality = var.get("causality", "local")
    variability = var.get("variability", "continuous")
    allowed = ALLOWED_INITIAL.get((causality, variability), (None,))
    return var.get("initial", allowed[0])


def combination_problems(root: Any) -> list[str]:
    """Each variable whose causality, variability, initial or start breaks section 2.2.7."""
    problems = []
    for var in root.iterfind("ModelVariables/ScalarVariable"):
        name, typed = var.get("name"), var[0]
        key = (var.get("causality", "local"), var.get("variability", "continuous"))
        allowed = ALLOWED_INITIAL.get(key)
        initial = _initial(var)
        if allowed is None or initial not in allowed:
            problems.append(f"{name}: causality/variability {key} with initial {initial!r}")
        if key[1] == "continuous" and typed.tag != "Real":
            problems.append(f"{name}: a continuous {typed.tag}")
        needs_start = initial in ("exact", "approx") or key[0] == "input"
        if needs_start != (typed.get("start") is not None):
            problems.append(f"{name}: start {'missing' if needs_start else 'forbidden'}")
        if typed.get("start") is not None and typed.tag in ("Real", "Integer"):
            start = float(typed.get("start"))
            if not float(typed.get("min", "-inf")) <= start <= float(typed.get("max", "inf")):
                problems.append(f"{name}: start {start} outside its min/max")
    return problems


def structure_problems(root: Any) -> list[str]:
    """What ModelStructure (section 2.2.8) gets wrong: every output in Outputs, every
    output or calculated parameter computed in initialisation in InitialUnknowns, both in
    index order, dependencies naming only knowns."""
    variables = root.findall("ModelVariables/ScalarVariable")
    index = {i: v for i, v in enumerate(variables, start=1)}
    outputs = [i for i, v in index.items() if v.get("causality") == "output"]
    initial = [
        i
        for i, v in index.items()
        if (v.get("causality") == "output" and _initial(v) in ("approx", "calculated"))
        or v.get("causality") == "calculatedParameter"
    ]
    listed = {
        part: [int(u.get("index")) for u in root.iterfind(f"ModelStructure/{part}/Unknown")]
        for part in ("Outputs", "InitialUnknowns")
    }
    problems = []
    if listed["Outputs"] != outputs:
        problems.append(f"Outputs lists {listed['Outputs']}, expected {outputs}")
    if listed["InitialUnknowns"] != initial:
        problems.append(f"InitialUnknowns lists {listed['InitialUnknowns']}, expected {initial}")
    knowns = {i for i, v in index.items() if v.get("causality") == "input"}
    knowns |= {i for i, v in index.items() if _initial(v) == "exact"}
    for unknown in root.iterfind("ModelStructure/InitialUnknowns/Unknown"):
        named = {int(d) for d in unknown.get("dependencies", "").split()}
        if named - knowns:
            problems.append(f"index {unknown.get('index')} depends on non-knowns {named - knowns}")
    return problems


def exponents_of(unit: str) -> dict[str, int]:
    """SI base-unit exponents a unit's name says (``N.m/rad``, ``kg.m2``, ``s2/rad2``)."""
    exponents: dict[str, int] = {}
    numerator, _, denominator = unit.partition("/")
    for part, sign in ((numerator, 1), (denominator, -1)):
        for factor in filter(None, part.split(".")):
            symbol, power = re.fullmatch(r"([A-Za-z]+|1)(\d*)", factor).groups()
            for base, exponent in SI_SYMBOLS[symbol].items():
                exponents[base] = exponents.get(base, 0) + sign * int(power or 1) * exponent
    return {base: e for base, e in exponents.items() if e}


def unit_problems(root: Any) -> list[str]:
    """Units used but not declared, base units that do not match the unit's name, display
    units that are not the FMI 2.0 ``display = factor * value + offset`` of degrees."""
    declared = {u.get("name"): u for u in root.iterfind("UnitDefinitions/Unit")}
    problems = []
    for typed in root.iterfind("ModelVariables/ScalarVariable/Real"):
        unit, display = typed.get("unit"), typed.get("displayUnit")
        if unit not in declared:
            problems.append(f"unit {unit!r} used but not declared")
        elif display is not None and declared[unit].find(f"DisplayUnit[@name='{display}']") is None:
            problems.append(f"display unit {display!r} is not one of {unit!r}'s")
    for name, unit in declared.items():
        base = unit.find("BaseUnit")
        given = {k: int(v) for k, v in (base.attrib if base is not None else {}).items()}
        if given != exponents_of(name):
            problems.append(f"unit {name!r} declares {given}, its name says {exponents_of(name)}")
        for display in unit.iterfind("DisplayUnit"):
            factor = float(display.get("factor", "1")) * DEGREE
            if not display.get("name").startswith("deg") or not math.isclose(factor, 1.0):
                problems.append(f"display unit {display.get('name')!r} of {name!r}: {factor}")
    return problems


@pytest.fixture(scope="module")
def schema() -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(FMI2_SCHEMA)))


@pytest.mark.parametrize("name", sorted(FMUS))
def test_the_model_description_follows_the_fmi2_schema_and_rules(
    name: str, fmu_paths: dict[str, Path], schema: etree.XMLSchema
) -> None:
    """The schema, then the rules of the standard's text no schema checks."""
    root = _root(fmu_paths[name])
    assert schema.validate(etree.ElementTree(root)), schema.error_log.last_error
    assert combination_problems(root) == []
    assert structure_problems(root) == []
    assert unit_problems(root) == []
    assert root.get("variableNamingConvention") in ("flat", "structured")
    if root.get("variableNamingConvention") == "structured":
        names = [v.get("name") for v in root.iterfind("ModelVariables/ScalarVariable")]
        assert [n for n in names if not STRUCTURED_NAME.fullmatch(n)] == []


def test_the_unit_checks_catch_a_wrong_declaration() -> None:
    """The checks above find what they look for: a unit whose exponents contradict its
    name, a combination the table forbids, a calculated output with a start value."""
    root = etree.fromstring(
        b'<fmiModelDescription><UnitDefinitions><Unit name="m/s"><BaseUnit m="1"/></Unit>'
        b"</UnitDefinitions><ModelVariables>"
        b'<ScalarVariable name="x" causality="input" variability="fixed"><Real start="0" '
        b'unit="m/s"/></ScalarVariable><ScalarVariable name="y" causality="output" '
        b'initial="calculated"><Real start="1" unit="m/s"/></ScalarVariable>'
        b"</ModelVariables></fmiModelDescription>"
    )
    assert exponents_of("N.m/rad") == {"kg": 1, "m": 2, "s": -2, "rad": -1}
    assert len(unit_problems(root)) == 1
    assert combination_problems(root) == [
        "x: causality/variability ('input', 'fixed') with initial None",
        "y: start forbidden",
    ]


@pytest.mark.parametrize("name", sorted(FMUS))
def test_the_documentation_page_states_the_default_experiment(
    name: str, fmu_paths: dict[str, Path]
) -> None:
    md = read_model_description(str(fmu_paths[name]))
    experiment = md.defaultExperiment
    with zipfile.ZipFile(fmu_paths[name]) as archive:
        page = archive.read("documentation/index.html").decode()
    assert experiment is not None and float(experiment.stepSize) > 0
    assert (
        f"start {experiment.startTime} s, stop {experiment.stopTime} s, "
        f"communication step {experiment.stepSize} s"
    ) in page


SETTABLE = """
import json, sys
from fmpy import read_model_description
from fmu_harness import Harness, status_of

path = sys.argv[1]
variables = read_model_description(path).modelVariables
def typed(v):
    return {"Real": float, "Integer": int, "Boolean": lambda s: s in ("true", "1"),
            "String": str}[v.type](v.start)
exact = [v for v in variables if v.variability != "constant"
         and (v.initial or ("exact" if v.causality == "parameter" else None))
         in ("exact", "approx")]
fmu = Harness(path, initialize=False)
refused = [v.name for v in exact if status_of(fmu.set, **{v.name: typed(v)})]
fmu.slave.setupExperiment(startTime=0.0)
fmu.slave.enterInitializationMode()
initial = [v for v in variables if v.causality == "input" or v in exact and v.initial != "approx"]
refused += [v.name for v in initial if status_of(fmu.set, **{v.name: typed(v)})]
fmu.close()
print(json.dumps(refused))
"""


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_every_variable_fmi_lets_a_host_set_before_initialisation_takes_its_start(
    name: str, fmu_paths: dict[str, Path], run_python: Any
) -> None:
    """FMI 2.0 (section 4.2.4) lets a host set a variable with initial "exact" or "approx"
    after instantiation, and one with initial "exact" or an input in initialisation mode
    (some hosts write every start value so); each takes its own start value there. (The
    autopilot declared its commands initial="exact" but refused any write to them.)"""
    done = run_python(SETTABLE, fmu_paths[name])
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout.strip().splitlines()[-1]) == []


def test_a_scenario_giving_an_autopilot_command_a_start_value_is_refused_at_load(
    fmu_paths: dict[str, Path],
) -> None:
    """The commands are the autopilot's to compute: a start value for one is refused as
    the scenario loads, naming its initial (it loaded, then the run failed at t = 0 with
    "fin_angle = 0.1 refused: an output cannot be set")."""
    text = (
        f'id = "command-start"\nstop_time = 1.0\n[coupling]\nstep = 0.01\n'
        f'[instances.controller]\nfmu = "{fmu_paths["AuvAutopilot"]}"\n'
        f"[instances.controller.start]\nfin_angle = 0.1\n"
    )
    with pytest.raises(ScenarioError, match=r"controller.fin_angle is a discrete output "
                       r"\(initial 'calculated'\)"):  # fmt: skip
        scenario_from_toml(text)


DEPENDENCIES = """
import json, sys
from fmpy import read_model_description
from fmu_harness import Harness

path = sys.argv[1]
md = read_model_description(path)
index = {v.name: i for i, v in enumerate(md.modelVariables, start=1)}
unknowns = [u.variable for u in md.initialUnknowns]
declared = {u.variable.name: {index[d.name] for d in u.dependencies} for u in md.initialUnknowns}
def nudged(v, down=False):
    start = {"Real": float, "Integer": int}[v.type](v.start)
    if v.type == "Integer":
        up = not down and (v.max is None or start + 1 <= int(v.max))
        return start + 1 if up else start - 1
    step = max(abs(start) * 0.1, 0.05)
    up = not down and (v.max is None or start + step <= float(v.max))
    return start + step if up else start - step
def initial_values(**values):
    fmu = Harness(path, initialize=False)
    fmu.slave.setupExperiment(startTime=0.0)
    fmu.slave.enterInitializationMode()
    fmu.set(**values)
    read = [fmu.slave.getReal([u.valueReference])[0] for u in unknowns]
    fmu.close()
    return read
base = initial_values()
undeclared = []
for known in md.modelVariables:
    if known.causality not in ("input", "parameter") or known.type not in ("Real", "Integer"):
        continue
    try:  # up, unless a bound no declared max states refuses it (a stroke past the hull)
        now = initial_values(**{known.name: nudged(known)})
    except Exception:
        now = initial_values(**{known.name: nudged(known, down=True)})
    undeclared += [f"{u.name} on {known.name}" for u, a, b in zip(unknowns, base, now)
                   if a != b and index[known.name] not in declared[u.name]]
fmu = Harness(path)
fmu.step(0.01)
outputs = [u.variable for u in md.outputs]
before = fmu.get_all(v.name for v in outputs)
feedthrough = []
for known in (v for v in md.modelVariables if v.causality == "input"):
    fmu.set(**{known.name: nudged(known)})
    after = fmu.get_all(v.name for v in outputs)
    feedthrough += [f"{v.name} on {known.name}" for v, a, b in zip(outputs, before, after)
                    if a != b]
fmu.close()
print(json.dumps({"undeclared": undeclared, "feedthrough": feedthrough}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_model_structure_dependencies_hold_when_each_known_is_nudged(
    name: str, fmu_paths: dict[str, Path], run_python: Any
) -> None:
    """Each Real or Integer input and parameter nudged alone in initialisation mode moves
    no initial unknown that does not list it; an input nudged after a step moves no output
    (ModelStructure/Outputs declares no direct feedthrough)."""
    done = run_python(DEPENDENCIES, fmu_paths[name])
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout.strip().splitlines()[-1]) == {
        "undeclared": [],
        "feedthrough": [],
    }


def _fmu_variables(archive: zipfile.ZipFile, source: str) -> dict[str, Any]:
    md = read_model_description(io.BytesIO(archive.read(source)))
    return {v.name: v for v in md.modelVariables}


def ssd_problems(archive: zipfile.ZipFile) -> list[str]:
    """Connectors and parameter values of an SSD that contradict the FMUs it packages."""
    root = etree.fromstring(archive.read("SystemStructure.ssd"))
    problems = []
    for comp in root.iterfind(".//ssd:Component", NS):
        if comp.get("source") not in archive.namelist():
            problems.append(f"{comp.get('name')}: {comp.get('source')} is not in the archive")
            continue
        variables = _fmu_variables(archive, comp.get("source"))
        for connector in comp.iterfind("ssd:Connectors/ssd:Connector", NS):
            var = variables[connector.get("name")]
            got = (
                connector.get("kind"),
                etree.QName(connector[0]).localname,
                connector[0].get("unit"),
            )
            if got != (var.causality, var.type, var.unit):
                problems.append(f"connector {var.name}: {got}")
        for parameter in comp.iterfind(".//ssv:Parameter", NS):
            var, value = variables[parameter.get("name")], parameter[0]
            if var.causality not in ("parameter", "input") and var.initial != "exact":
                problems.append(f"start value for {var.name}, an {var.initial} {var.causality}")
            if (etree.QName(value).localname, value.get("unit")) != (var.type, var.unit):
                problems.append(f"parameter {var.name}: {value.tag} {value.get('unit')}")
    return problems


@pytest.mark.parametrize("scenario_id", ["survey", "bs-3", "cur-1", "vert-1"])
def test_an_exported_ssp_follows_the_ssp_schema_and_its_fmus(
    scenario_id: str, fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """Built-in scenarios (the survey: three FMUs; Real, Integer, Boolean and String
    values): the SSD is valid, each component's FMU is inside the archive at its
    ``source``, connectors carry their variable's causality, type and unit, parameter
    values their variable's type and unit, and each unit is declared as its name says."""
    scenario = load_scenario(scenario_id, fmu_paths["AuvPlant"].parent)
    with zipfile.ZipFile(export_ssp(scenario, tmp_path / "exported.ssp")) as archive:
        root = etree.fromstring(archive.read("SystemStructure.ssd"))
        schema = etree.XMLSchema(etree.parse(str(SSD_SCHEMA)))
        assert schema.validate(etree.ElementTree(root)), schema.error_log.last_error
        assert ssd_problems(archive) == []
    units = {u.get("name"): u.find("ssc:BaseUnit", NS) for u in root.iterfind(".//ssc:Unit", NS)}
    used = {e.get("unit") for e in root.iter() if e.get("unit")}
    assert used <= set(units)
    assert {n: {k: int(v) for k, v in units[n].attrib.items()} for n in used} == {
        n: exponents_of(n) for n in used
    }
