"""The runtime's C (``fmu_runtime/native/``) and the C test hosts pass static analysis: the
runtime compiles without a diagnostic under the stricter warnings of
``cosim.fmus.native.STRICT_WARNINGS`` and GCC's static analyser (``-fanalyzer``), both with
``-Werror``, so that a change cannot bring in a new finding (an unchecked allocation, a
leak on an error path, a NULL dereference, a lossy conversion); so does zig's clang, the
win64 cross-compiler (``platform_win32.c`` too), under the stricter warnings. The C test
hosts (and the libraries the tests preload) are held to the analyser as well. Skipped where
the system compiler is not a GCC with the analyser, or without the ``ziglang`` package."""

from __future__ import annotations

import re
import subprocess
from functools import cache
from pathlib import Path

import pytest
from c_hosts import sanitizing_toolchain

from cosim.fmus import native

pytestmark = pytest.mark.slow  # the analyser takes 5 to 15 s over the runtime

HOSTS = sorted((Path(__file__).parent / "hosts").glob("*.c"))
WIN64_ONLY = {"win64_host.c"}  # includes windows.h
# one finding: "file.c:LINE:COL: warning: ... [-Wflag]" (an error under -Werror)
FINDING = re.compile(r"^\S+\.[ch]:\d+:\d+: (?:warning|error): .*$", re.MULTILINE)


@cache
def _analyser() -> tuple[str, ...]:
    """The system compiler's command if it has GCC's analyser, else the test is skipped."""
    command = sanitizing_toolchain().command
    done = subprocess.run(
        [*command, *native.ANALYZER, "-x", "c", "-c", "-o", "/dev/null", "-"],
        input="int f(void) { return 0; }\n",
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        pytest.skip(f"{command[0]} has no static analyser (-fanalyzer needs GCC 10 or later)")
    return command


def _findings(stderr: str) -> str:
    return "\n".join(FINDING.findall(stderr)) or stderr[-3000:]


def test_the_runtime_has_no_finding_under_strict_warnings_and_the_analyser(tmp_path):
    """Every finding, listed as file:line, fails the test; fix it, or silence it where it
    is with a comment saying why it is not a defect."""
    _analyser()
    out = tmp_path / "runtime.so"
    command = native.compile_command(
        sanitizing_toolchain(), out, *native.STRICT_WARNINGS, *native.ANALYZER, "-Werror"
    )
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0 and "warning" not in done.stderr, _findings(done.stderr)


@pytest.mark.parametrize(
    "host", [h for h in HOSTS if h.name not in WIN64_ONLY], ids=lambda h: h.name
)
def test_a_c_host_has_no_finding_under_the_analyser(host, tmp_path):
    command = _analyser()
    flags = ("-O1", "-Wall", "-Wextra", *native.ANALYZER, "-Werror")
    done = subprocess.run(
        [*command, *flags, "-c", "-o", str(tmp_path / "host.o"), str(host)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0 and "warning" not in done.stderr, _findings(done.stderr)


@pytest.mark.parametrize("platform", ["linux64", "win64"])
def test_the_runtime_has_no_finding_under_strict_warnings_with_zig(platform, tmp_path):
    """clang warns where GCC does not (a float constant passed as a double)."""
    cross = native.zig()
    if cross is None:
        pytest.skip("ziglang not installed")
    out = tmp_path / f"runtime{native.SUFFIXES[platform]}"
    command = native.compile_command(
        cross, out, *native.STRICT_WARNINGS, "-Werror", platform=platform
    )
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0 and "warning" not in done.stderr, _findings(done.stderr)
