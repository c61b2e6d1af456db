"""The documentation stays true to the repository.

* Every pointer to a file of the repository, in code and docs (``docs/model.md#lqr`` in a
  docstring, ``fmu_runtime/native/probe.c`` in a page, a Markdown link
  ``[..](reproduction.md)`` in a page or a notebook), names a file that exists and, with
  a ``#section``, a heading that exists in it.
* ``docs/model.md``: its parameter table holds remus100's values and units, every entry of
  its equation index names a function that exists, and every equation number the code and
  the docs cite is in the index; its lift moments leave the Munk moment to the added mass,
  and every coefficient a body of revolution would not have is named where that is argued.
* ``docs/interfaces.md`` is what ``scripts/interfaces_doc.py`` writes for the built FMUs.
"""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest
from repo_paths import ROOT, script_module

from plant_fmu.model.parameters import VehicleParameters, load_vehicle

MODEL_DOC = ROOT / "docs" / "model.md"
# .pytest_cache: it holds downloaded packages (tests/fmu_runtime/windows_cpython.py)
SKIPPED_FOLDERS = {".git", ".venv", "build", "runs", "auv_cosim.egg-info", "__pycache__",
                   ".pytest_cache"}  # fmt: skip
PACKAGES = ("docs", "plant_fmu", "controller_fmu", "fmu_runtime", "cosim", "scripts", "tests")
REPO_PATH = re.compile(rf"(?<![\w/.-])((?:{'|'.join(PACKAGES)})/[\w./-]*\w\.[a-z0-9]+)(#[\w-]+)?")
MARKDOWN_LINK = re.compile(r"\]\((?!https?:|mailto:)([^)\s#]*)(#[\w-]+)?\)")
EQUATION = re.compile(r"\(((?:\d|A)\.\d+(?:\.\d+)?)\)")


def _files(*suffixes: str) -> list[Path]:
    # a virtual environment in the clone, whatever its name (the README's .venv, or .v)
    skipped = SKIPPED_FOLDERS | {cfg.parent.name for cfg in ROOT.glob("*/pyvenv.cfg")}
    return sorted(
        path
        for path in ROOT.rglob("*")
        if path.suffix in suffixes
        and path.is_file()
        and not skipped & set(path.relative_to(ROOT).parts)
    )


def _anchors(markdown: Path) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    headings = re.findall(r"^#+\s+(.+?)\s*$", markdown.read_text(encoding="utf-8"), re.M)
    return {re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-") for h in headings}


def _pointers() -> list[tuple[Path, Path, str | None]]:
    """(file, target, anchor) of every pointer to a repository file."""
    found = []
    for path in _files(".py", ".md", ".toml", ".ipynb"):
        text = path.read_text(encoding="utf-8")
        for match in REPO_PATH.finditer(text):
            found.append((path, ROOT / match[1], match[2]))
        if path.suffix in (".md", ".ipynb"):  # a notebook's Markdown cells, in its JSON
            for match in MARKDOWN_LINK.finditer(text):
                target = (path.parent / match[1]) if match[1] else path
                found.append((path, target, match[2]))
    return found


def test_every_pointer_names_a_file_and_section_of_the_repository():
    pointers = _pointers()
    assert len(pointers) > 20
    broken = []
    for source, target, anchor in pointers:
        where = source.relative_to(ROOT)
        if not target.exists():
            broken.append(f"{where}: {target.relative_to(ROOT)} does not exist")
        elif anchor and anchor[1:] not in _anchors(target):
            broken.append(f"{where}: no section {anchor} in {target.relative_to(ROOT)}")
    assert not broken, "\n".join(broken)


def _table(heading: str) -> list[list[str]]:
    """The rows (cells, backticks kept) of the first table after ``heading``."""
    text = MODEL_DOC.read_text(encoding="utf-8")
    section = text.split(heading, 1)[1]
    rows = [line for line in section.splitlines() if line.startswith("|")]
    table = []
    for line in rows:
        cells = [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        if table and len(cells) != len(table[0]):
            break  # the next table
        table.append(cells)
    return table[2:]  # past the header and its rule


def test_parameter_table_is_remus100():
    params = load_vehicle("remus100")
    rows = {row[0].strip("`"): row for row in _table("`remus100`, field by field")}
    physical = [
        name for name in VehicleParameters.field_info() if name not in ("name", "description")
    ]
    assert sorted(rows) == sorted(physical)
    for name in physical:
        _, _, _, value, unit, _ = rows[name]
        assert float(value) == pytest.approx(getattr(params, name), rel=1e-4), name
        described = VehicleParameters.field_info()[name].description
        assert unit == described.rsplit(", ", 1)[1].split(" (")[0], name


def test_the_lift_moments_leave_the_munk_moment_to_the_added_mass():
    """N_uv (Table 5.1) and M_uw (Table 6.3) are lift moments without the Munk moment: the
    plant takes that from the added mass ((5.1.30)'s (a22 - a11) u v, and its mirror in
    pitch), so its moment from sway at U0 is (N_uv - (a22 - a11)) U0 and from heave
    (M_uw + a33 - a11) U0. N_uv's description and the parameter table said it included
    the Munk moment, which the plant would then count twice."""
    from plant_fmu.model.dynamics import PlantModel, Variant
    from plant_fmu.model.linearization import input_vector, linearize, state_vector

    params, u0 = load_vehicle("remus100"), 1.525
    model = PlantModel(params, Variant.FULL)
    velocities = ["u", "v", "w", "p", "q", "r"]
    A, _ = linearize(
        model, state_vector({"u": u0}), input_vector({"thrust": 9.0}), velocities, ["fin_angle"]
    )
    forces = model.mass_matrix @ A  # [X, Y, Z, K, M, N] over the velocities
    yaw, pitch = forces[5, 1], forces[4, 2]
    assert yaw == pytest.approx((params.N_uv - (params.a22 - params.a11)) * u0, rel=1e-6)
    assert pitch == pytest.approx((params.M_uw + (params.a33 - params.a11)) * u0, rel=1e-6)
    rows = {row[0].strip("`"): row for row in _table("`remus100`, field by field")}
    for name in ("N_uv", "M_uw"):
        described = (VehicleParameters.field_info()[name].description, rows[name][2])
        wrong = [text for text in described if re.search(r"with the Munk|Munk moment incl", text)]
        assert not wrong, f"{name}: {wrong} counts the Munk moment in the coefficient"


# A body of revolution's vertical coefficients are its horizontal ones under the turn of the
# body frame by 90 deg about x, (v, r) -> (w, -q), Y -> Z, N -> -M: (horizontal, vertical,
# sign, how the docs write them)
REVOLUTION_MAP = (
    ("Y_vv", "Z_ww", 1, "Y_v|v|", "Z_w|w|"),
    ("Y_uv", "Z_uw", 1, "Y_uv", "Z_uw"),
    ("Y_ur", "Z_uq", -1, "Y_ur", "Z_uq"),
    ("Y_rr", "Z_qq", -1, "Y_r|r|", "Z_q|q|"),
    ("N_vv", "M_ww", -1, "N_v|v|", "M_w|w|"),
    ("N_uv", "M_uw", -1, "N_uv", "M_uw"),
    ("N_ur", "M_uq", 1, "N_ur", "M_uq"),
    ("N_rr", "M_qq", 1, "N_r|r|", "M_q|q|"),
    ("a22", "a33", 1, "a22", "a33"),
    ("a26", "a35", -1, "a26", "a35"),
    ("a66", "a55", 1, "a66", "a55"),
    ("I_zz", "I_yy", 1, "I_zz", "I_yy"),
)


def test_every_departure_from_the_body_of_revolution_is_named_where_the_map_is_argued():
    """M_uq's sign is corrected with the argument that the vertical coefficients are the
    horizontal ones turned 90 deg about x; the same map does not give Table 6.3's
    M_q|q| = -188 (N_r|r| = -94), which remus100 keeps. Every coefficient of remus100 the
    map does not give is named, with both values, in the corrections and in the model
    choice that argues the map (the choice listed only the coefficients that fit it)."""
    from reference_values import DISSERTATION

    from cosim.reproduction.catalogue import catalogue

    params = load_vehicle("remus100")
    corrections = MODEL_DOC.read_text(encoding="utf-8").split("## Corrections and choices")[1]
    choice = next(
        c.why
        for section in catalogue(DISSERTATION)
        for c in section.choices
        if c.choice.startswith("M_uq")
    )
    departures = [
        (f"{h_label} = {getattr(params, h):g}", f"{v_label} = {getattr(params, v):g}")
        for h, v, sign, h_label, v_label in REVOLUTION_MAP
        if getattr(params, v) != sign * getattr(params, h)
    ]
    assert len(departures) == 1  # the test sees one, and the texts must name it
    texts = {"docs/model.md's corrections": corrections.replace("`", ""), "the choice": choice}
    for where, text in texts.items():
        missing = [value for pair in departures for value in pair if value not in text]
        assert not missing, f"{missing} not named in {where}"


def test_the_scenario_table_gives_each_scenario_the_gains_it_runs():
    """docs/model.md's table of the built-in scenarios names the backstepping gains k0, k1
    where they differ from the defaults, and "same" repeats the row above; each row's gains
    must be those its scenario file runs (cur-2, slow-1 and slow-2 read "same" as cur-1's
    k0 = 0.5, k1 = 1, and run Sec. 6.3.3's 0.3 and 0.8)."""
    import tomllib

    from controller_fmu.autopilot import AutopilotConfig

    defaults = AutopilotConfig.build()
    wrong, controller = [], ""
    for scenario, cell, *_ in _table("## Scenarios"):
        controller = controller if cell.startswith("same") else cell
        stated = dict(re.findall(r"\b(k[01]) = ([\d.]+)", controller))
        path = ROOT / "cosim" / "scenarios" / f"{scenario}.toml"
        start = tomllib.loads(path.read_text(encoding="utf-8"))["instances"]["controller"]
        for gain in ("k0", "k1"):
            runs = start["start"].get(gain, getattr(defaults, gain))
            if float(stated.get(gain, getattr(defaults, gain))) != runs:
                wrong.append(f"{scenario}: {gain} = {runs}, the table says {controller!r}")
    assert not wrong, wrong


def _index_targets() -> list[tuple[str, str]]:
    targets = []
    for row in _table("## Equation index"):
        targets += re.findall(r"`([\w/]+\.py): ([\w.]+)`", row[2])
    return targets


def test_equation_index_names_functions_that_exist():
    targets = _index_targets()
    assert len(targets) > 30
    for path, name in targets:
        if path.startswith(("scripts/", "tests/")):  # not importable: look for the definition
            assert re.search(rf"^def {name}\(", (ROOT / path).read_text(), re.M), (path, name)
            continue
        obj = importlib.import_module(path.removesuffix(".py").replace("/", "."))
        for part in name.split("."):
            obj = getattr(obj, part)  # AttributeError names what is missing


def _covered(number: str, cell: str) -> bool:
    """``number`` is named in ``cell``, alone or inside a range (a)-(b) of one chapter."""
    if f"({number})" in cell:
        return True
    *chapter, last = number.split(".")
    for low, high in re.findall(r"\(([\w.]+)\)-\(([\w.]+)\)", cell):
        *low_chapter, low_last = low.split(".")
        *high_chapter, high_last = high.split(".")
        if low_chapter == high_chapter == chapter and int(low_last) <= int(last) <= int(high_last):
            return True
    return False


def test_every_equation_the_code_and_the_docs_cite_is_in_the_index():
    """Every dissertation equation number cited in the code, in the docs (the model page
    itself, the reproduction page) and in the printed values is in the index (the model
    page cited (5.1.64) and (6.3.6), which the index lacked)."""
    index = [row[0] for row in _table("## Equation index")]
    cited = {
        (number, path.relative_to(ROOT).as_posix())
        for path in _files(".py", ".md", ".toml")
        for number in EQUATION.findall(path.read_text(encoding="utf-8"))
        if re.fullmatch(r"[2-6]\.\d+\.\d+|A\.\d+", number)
    }
    assert len({n for n, _ in cited}) > 40
    assert any(where.startswith("docs/") for _, where in cited)
    missing = sorted(c for c in cited if not any(_covered(c[0], cell) for cell in index))
    assert not missing, missing


@pytest.mark.slow
def test_interfaces_page_is_current(fmu_paths):
    """Regenerate with ``python scripts/interfaces_doc.py`` when an FMU variable changes."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    assert fmu_paths["AuvAutopilot"].parent == fmu_dir
    script = ROOT / "scripts" / "interfaces_doc.py"
    check = [sys.executable, str(script), "--fmu-dir", str(fmu_dir), "--check"]
    done = subprocess.run(check, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr


def test_the_user_benchmark_times_the_example_study_of_the_docs(tmp_path):
    """scripts/bench_user.py reads the study it times out of docs/studies.md, so the figure
    it publishes is for the study the docs show: eight runs of bs-3 on a grid."""
    bench_user = script_module("bench_user")
    from cosim.study.spec import load_study

    path = tmp_path / "study.toml"
    path.write_text(bench_user.STUDY)
    spec = load_study(path)
    assert spec.scenario == "bs-3" and spec.stop_time == 20.0
    assert spec.grid == {"plant.v_0": [-0.10, -0.05, 0.05, 0.10], "controller.k0": [0.2, 0.5]}


NUMBER_WORDS = {2: "two", 3: "three", 4: "four", 10: "ten"}


def test_the_texts_that_count_the_fmus_count_the_ones_built(capsys):
    """``auv-cosim --help`` and the quickstart notebook's introduction count the FMUs
    ``auv-cosim build`` builds (they said two when the guidance made three), name each,
    and put the first build at seconds, not a minute; docs/hosts.md, which hands them to
    other FMI tools, names each in its opening (it named the plant and the autopilot only)."""
    import json

    from cosim.cli import main
    from cosim.fmus.build import FMUS

    with pytest.raises(SystemExit):
        main(["--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    notebook = json.loads((ROOT / "docs" / "notebooks" / "quickstart.ipynb").read_text("utf-8"))
    introduction = " ".join("".join(notebook["cells"][0]["source"]).split())
    for text in (help_text, introduction):
        assert f"{NUMBER_WORDS[len(FMUS)]} FMI 2.0 FMUs" in text, text
    assert all(name in help_text for name in FMUS), help_text
    hosts = (ROOT / "docs" / "hosts.md").read_text(encoding="utf-8").split("\n\n")[1]
    unnamed = [f"{name}.fmu" for name in FMUS if f"`{name}.fmu`" not in hosts]
    assert not unnamed, f"docs/hosts.md's opening does not name {unnamed}"
    assert "about a minute" not in introduction


def test_contributing_states_the_test_settings_pyproject_makes():
    """CONTRIBUTING.md's time limit per test, its count of the slowest tests listed and its
    markers are pyproject.toml's (it said 600 s while pyproject set 900)."""
    import tomllib

    pytest_ini = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"][
        "pytest"
    ]["ini_options"]
    text = (ROOT / "CONTRIBUTING.md").read_text(encoding="utf-8")
    limit = re.search(r"\(`pytest-timeout`, (\d+) s by default\)", text)
    assert limit and int(limit[1]) == pytest_ini["timeout"], limit
    durations = re.search(r"--durations=(\d+)", pytest_ini["addopts"])
    assert durations and f"the slowest {NUMBER_WORDS.get(int(durations[1]), durations[1])}" in text
    registered = {marker.split(":")[0] for marker in pytest_ini["markers"]}
    assert set(re.findall(r"^- `(\w+)`: ", text, re.MULTILINE)) == registered


def _models_in(annotation: object) -> list[type]:
    """The pydantic models an annotation holds (``X | None``, ``list[X]``, ``dict[str, X]``)."""
    import typing

    from pydantic import BaseModel

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models_in(arg)]


def _schema_keys(model: type, prefix: str = "") -> set[str]:
    """Every key path (``coupling.step``, ``events.when``) a file ``model`` validates takes;
    an entry of a list or a dict of tables is its table's keys, a free dict (``start``) a leaf."""
    keys = set()
    for name, field in model.model_fields.items():
        key = prefix + (field.alias or name)
        keys.add(key)
        for inner in _models_in(field.annotation):
            keys |= _schema_keys(inner, key + ".")
    return keys


def _written_keys(data: dict, model: type, prefix: str = "") -> set[str]:
    """The key paths of parsed TOML ``data`` as :func:`_schema_keys` names them."""
    import typing

    fields = {field.alias or name: field for name, field in model.model_fields.items()}
    keys = set()
    for key, value in data.items():
        keys.add(prefix + key)
        inner = _models_in(fields[key].annotation) if key in fields else []
        if not inner:
            continue
        tables = value if isinstance(value, list) else [value]
        if typing.get_origin(fields[key].annotation) is dict:  # [instances.<name>]
            tables = list(value.values())
        for table in tables:
            keys |= _written_keys(table, inner[0], f"{prefix}{key}.")
    return keys


def test_the_example_scenario_writes_every_key_the_schema_takes():
    """docs/scenario-example.toml is "the one statement of the format", using every key (the
    README says so): each key a scenario file may hold is written in it, commented out or
    not, and it writes no key the schema refuses (``[coupling] error_estimate`` was missing)."""
    import tomllib

    from cosim.scenario.spec import ScenarioSpec

    text = (ROOT / "docs" / "scenario-example.toml").read_text(encoding="utf-8")
    uncommented = re.sub(r"^# (\w+ = )", r"\1", text, flags=re.MULTILINE)
    written = _written_keys(tomllib.loads(uncommented), ScenarioSpec)
    schema = _schema_keys(ScenarioSpec)
    assert not schema - written, f"keys the example does not show: {sorted(schema - written)}"
    assert not written - schema, f"keys no scenario takes: {sorted(written - schema)}"


def test_a_documented_command_in_an_empty_environment_keeps_its_temporary_folder():
    """docs/hosts.md ran ecos under `env -i`, which dropped TMPDIR: ecos unpacked the SSP
    into /tmp and left it there (ecos_ssp_<uuid>), on every machine that ran the page's
    example (the test suite's too, whose TMPDIR is its own folder). A command line a doc
    starts with `env -i` passes TMPDIR on."""
    bare = [
        f"{path.relative_to(ROOT)}:{number}"
        for path in _files(".md")
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if line.lstrip().startswith("env -i ") and "TMPDIR=" not in line
    ]
    assert bare == []
