"""What a user learns from ``help()`` and tab completion alone: every argument of the
public API named in its help with its allowed values, the objects a run hands back
described with their units, only the API offered by ``cosim.<Tab>``, and the examples
of the help run as shown."""

from __future__ import annotations

import dataclasses
import inspect
import pydoc
import re
import shutil
import sys
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from process_group import run_in_group

import cosim
import cosim.api
from cosim.scenario import spec


def _public_callables() -> dict[str, Callable[..., Any]]:
    """The functions of ``cosim.__all__`` and the public methods of its classes."""
    found: dict[str, Callable[..., Any]] = {}
    for name in cosim.__all__:
        value = getattr(cosim, name)
        if inspect.isfunction(value):
            found[name] = value
        elif inspect.isclass(value):
            for method, member in vars(value).items():
                if inspect.isfunction(member) and not method.startswith("_"):
                    found[f"{name}.{method}"] = member
    return found


def _literal_choices(annotation: str) -> tuple[str, ...]:
    """The values of the ``Literal`` aliases an annotation string names (``Algorithm |
    None``: jacobi, gauss-seidel, adaptive)."""
    choices: list[str] = []
    for word in re.findall(r"\w+", annotation):
        alias = getattr(spec, word, None)
        if typing.get_origin(alias) is typing.Literal:
            choices.extend(typing.get_args(alias))
    return tuple(choices)


@pytest.mark.parametrize("name", sorted(_public_callables()))
def test_help_names_every_argument_and_the_values_it_takes(name: str) -> None:
    """``help(cosim.run)`` showed ``algorithm: 'Algorithm | None'`` and called it one of
    "the command line's coupling options": which values it takes (``"jacobi"``,
    ``"gauss-seidel"``, ``"adaptive"``) was in docs/api.md only, and ``help(scenario.
    with_overrides)`` never named ``error_estimate``. Each argument is named in its help,
    and one that takes a few strings lists them all."""
    function = _public_callables()[name]
    doc = inspect.getdoc(function) or ""
    text = " ".join(doc.split())
    for parameter in inspect.signature(function).parameters.values():
        if parameter.name == "self":
            continue
        # as code (``stop_time``, ``instance.name``) or a numpydoc entry (``a, b : ...``)
        named = re.search(rf"``[^`]*\b{parameter.name}\b[^`]*``", text) or re.search(
            rf"^[\w, ]*\b{parameter.name}\b[\w, ]* :", doc, re.M
        )
        assert named, f"{name}: help names no {parameter.name}"
        missing = [c for c in _literal_choices(str(parameter.annotation)) if c not in text]
        assert not missing, f"{name}: help of {parameter.name} lacks {missing}"


# the fields a caller reads (those the repr shows), and the units their help must give
UNITS = {
    spec.Scenario: {"stop_time": "s"},
    spec.Coupling: {"step": "s", "max_step": "s"},
    spec.Instance: {},
}


@pytest.mark.parametrize("kind", list(UNITS), ids=lambda kind: kind.__name__)
def test_help_of_a_scenario_describes_its_fields_with_their_units(kind: type) -> None:
    """``help(scenario)`` said only "A fully resolved scenario: what the master, the
    results and the exporters use", and ``help(scenario.coupling)`` gave no unit of its
    ``step``: the units were comments in the source. Every field a scenario's repr shows
    is described under Attributes, a time with its unit."""
    attributes = inspect.getdoc(kind).split("Attributes\n----------\n", 1)
    assert len(attributes) == 2, f"{kind.__name__}: no Attributes section in its help"
    described = {}
    for match in re.finditer(r"^([\w, ]+) : (.*)\n((?:    .*\n?)*)", attributes[1], re.M):
        for field in match[1].split(", "):
            described[field] = " ".join(f"{match[2]} {match[3]}".split())
    for field in dataclasses.fields(kind):
        if field.repr:
            assert field.name in described, f"{kind.__name__}.{field.name} is not described"
    for field, unit in UNITS[kind].items():
        assert re.search(rf"\b{unit}\b", described[field]), (field, described[field])
    assert "Attributes" in pydoc.render_doc(kind, renderer=pydoc.plaintext)


def test_tab_completion_offers_the_api_not_the_module_s_imports() -> None:
    """``cosim.<Tab>`` offered ``Any``, ``TYPE_CHECKING``, ``annotations`` and
    ``importlib`` beside ``run`` (the package's own imports), and not ``__version__``."""
    public = {name for name in dir(cosim) if not name.startswith("_")}
    modules = {name for name in public if getattr(getattr(cosim, name), "__name__", "")
               == f"cosim.{name}"}  # fmt: skip
    assert public - modules == set(cosim.__all__), sorted(public - modules - set(cosim.__all__))
    assert "__version__" in dir(cosim)


def test_a_public_code_example_is_a_doctest() -> None:
    """The package's help showed its example as a literal block (``::``), which no test
    ran: it swept a ``study.toml`` no user has. Every example in the help of ``cosim``,
    ``cosim.api`` and the public names is a ``>>>`` example, run by
    :func:`test_the_examples_in_the_help_run_as_shown`."""
    literal = [name for name, doc in _documented().items() if re.search(r"::\s*$", doc, re.M)]
    assert not literal, f"code shown as a literal block, not as >>> examples: {literal}"
    assert sum(">>>" in doc for doc in _documented().values()) >= 3


def _documented() -> dict[str, str]:
    """The help of ``cosim``, ``cosim.api`` and every public name, by name."""
    docs = {"cosim": cosim.__doc__ or "", "cosim.api": cosim.api.__doc__ or ""}
    for name in cosim.__all__:
        docs[name] = inspect.getdoc(getattr(cosim, name)) or ""
    docs |= {name: inspect.getdoc(f) or "" for name, f in _public_callables().items()}
    return docs


# run in a fresh interpreter, in a folder holding the built FMUs, as a user would (a
# study's workers import the main module again: hence the guard)
DOCTESTS = """
import doctest, inspect, sys
import cosim, cosim.api

if __name__ == "__main__":
    finder, runner = doctest.DocTestFinder(recurse=False), doctest.DocTestRunner()
    objects = [cosim, cosim.api] + [getattr(cosim, name) for name in cosim.__all__]
    for owner in list(objects):
        if inspect.isclass(owner):
            objects += [m for n, m in vars(owner).items() if inspect.isfunction(m)]
    for thing in objects:
        for test in finder.find(thing, getattr(thing, "__name__", None), globs={"cosim": cosim}):
            runner.run(test)
    print(f"attempted={runner.tries} failed={runner.failures}")
    sys.exit(1 if runner.failures else 0)
"""


@pytest.mark.slow
@pytest.mark.cluster
def test_the_examples_in_the_help_run_as_shown(fmu_paths: dict[str, Path], tmp_path: Path) -> None:
    """The ``>>>`` examples of ``help(cosim)``, ``help(cosim.run)``, ... give the output
    they show, run where ``auv-cosim build`` has built the FMUs."""
    fmus = tmp_path / "build" / "fmus"
    fmus.mkdir(parents=True)
    for path in fmu_paths.values():
        shutil.copyfile(path, fmus / path.name)
        shutil.copyfile(f"{path}.sha256", fmus / f"{path.name}.sha256")
    script = tmp_path / "doctests.py"
    script.write_text(DOCTESTS, encoding="utf-8")
    done = run_in_group([sys.executable, str(script)], timeout=600, cwd=tmp_path)
    assert done.returncode == 0, f"{done.stdout[-4000:]}\n{done.stderr[-2000:]}"
    attempted = int(re.search(r"attempted=(\d+)", done.stdout)[1])
    assert attempted >= 8, done.stdout
