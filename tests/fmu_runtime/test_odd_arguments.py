"""Odd arguments a C host hands fmi2Instantiate and fmi2SetDebugLogging
(``hosts/odd_arguments.c``), with the runtime and the host built with ASan and UBSan, on
both runtimes:

* an instance name that is empty or only white space is refused (FMI 2.0: at least one
  character that is not white space), as the FMU SDK refuses it;
* a resource location whose %00 would cut the path short (to another folder than the one
  it names), or of another scheme than ``file:``, is refused naming what is wrong; a
  ``FILE:`` scheme is ``file:`` (RFC 3986: schemes are case-insensitive);
* a GUID, resource location or log category that is not UTF-8 is refused with a message
  that is UTF-8 all the same, showing each byte that is not as ``\\xNN``, as Python's
  ``backslashreplace`` does (the log contract: every message UTF-8);
* nothing trips a sanitizer.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from c_hosts import SANITIZED_ENVIRONMENT, run_clean, sanitized_build, with_runtime

ODD_SOURCE = Path(__file__).parent / "hosts" / "odd_arguments.c"
RUNTIMES = {"runtime": "", "pythonfmu": "pythonfmu"}


def _cases(stdout: str) -> dict[str, tuple[str, list[str]]]:
    """Each case's answer and the messages logged during its call (those printed before
    its line, since the last case's)."""
    cases: dict[str, tuple[str, list[str]]] = {}
    logged: list[str] = []
    for line in stdout.splitlines():
        if line.startswith(("log ", "VIOLATION")):
            logged.append(line)
        elif match := re.fullmatch(r"([\w-]+) (NULL|instance|\d)", line):
            cases[match[1]] = (match[2], logged)
            logged = []
    return cases


@pytest.fixture(scope="module", params=sorted(RUNTIMES))
def cases(request, extracted, tmp_path_factory, clean_home) -> dict:
    folder = tmp_path_factory.mktemp("odd")
    runtime_so, host = sanitized_build(folder, ODD_SOURCE, ("-Wall", "-Wextra", "-Werror"))
    plant = with_runtime(extracted["AuvPlant"], runtime_so, folder / "AuvPlant")
    done = run_clean([host, plant, "AuvPlant"], clean_home, timeout=600,
                     **SANITIZED_ENVIRONMENT, AUV_FMU_RUNTIME=RUNTIMES[request.param])  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "Sanitizer" not in done.stderr and "runtime error" not in done.stderr, done.stderr
    return {"cases": _cases(done.stdout), "stdout": done.stdout, "plant": plant}


def _refused(cases: dict, case: str) -> str:
    """The one Error line the refused ``case`` logged."""
    answer, logged = cases["cases"][case]
    assert answer in ("NULL", "3"), (case, answer, logged)
    [line] = logged
    assert line.startswith(("log [3] {logStatusError} ", "VIOLATION")), line
    return line


@pytest.mark.slow
@pytest.mark.parametrize("case", ["name-empty", "name-blank"])
def test_an_instance_name_without_a_character_that_is_not_white_space_is_refused(case, cases):
    """An empty instance name, or one of spaces and tabs, was taken: every message then
    named no instance. FMI 2.0 asks for at least one character that is not white space."""
    line = _refused(cases, case)
    assert "instanceName" in line and "white space" in line, line


@pytest.mark.slow
def test_a_nul_escape_in_the_resource_location_is_refused(cases):
    """``file:///x/resources%00/../elsewhere`` was decoded to a path cut at the NUL byte,
    /x/resources, and the FMU was loaded from a folder the URI does not name."""
    line = _refused(cases, "uri-nul")
    assert "%00" in line and "NUL" in line, line


@pytest.mark.slow
def test_a_resource_location_of_another_scheme_is_refused_as_not_a_file_uri(cases):
    """``http://...`` was taken for a relative folder, refused as a missing
    fmu_runtime.txt there; now refused as a URI the FMU cannot read its resources from."""
    line = _refused(cases, "uri-http")
    assert "http://localhost" in line and "not a file: URI" in line, line


@pytest.mark.slow
def test_a_file_scheme_in_capital_letters_is_a_file_uri(cases):
    """``FILE:///x/resources`` was taken for a relative folder and refused."""
    assert cases["cases"]["uri-capital-scheme"][0] == "instance", cases["stdout"][-3000:]


@pytest.mark.slow
@pytest.mark.parametrize(
    "case, shown",
    [
        ("guid-not-utf8", r"GUID \xff{not a guid} is not this FMU's"),
        ("uri-not-utf8-escaped", r"/resources/\xff"),
        ("uri-not-utf8-raw", r"/resources/\xff"),
        ("category-not-utf8", r"log\xff\xfeSteps is not a log category"),
    ],
)
def test_host_text_that_is_not_utf8_is_quoted_in_a_utf8_message(case, shown, cases):
    """A refusal quoted the host's bytes as they were: a message that is not UTF-8, which a
    host decoding it strictly (Python's ``bytes.decode``) cannot show. Each byte that is
    no UTF-8 is shown as ``\\xNN`` now."""
    line = _refused(cases, case)
    assert "VIOLATION" not in line and shown in line, line


@pytest.mark.slow
def test_a_message_cut_short_is_cut_between_characters(cases):
    """A refusal longer than a log line quoting a host's UTF-8 (a GUID of 1,200 "é"s) was
    cut inside a character, whose first byte was then shown as ``\\xc3``: text the host
    handed in as UTF-8 shown as bytes that are not."""
    line = _refused(cases, "guid-long-utf8")
    assert "GUID x\u00e9\u00e9" in line, line[:200]
    assert "\\x" not in line, line[-200:]
