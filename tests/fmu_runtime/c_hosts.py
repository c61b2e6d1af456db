"""Helpers for running our FMUs in hosts that are not the test process (the fixtures that
use them are in this folder's conftest.py):

* :func:`run_clean`: a command in a clean environment (``env -i`` with PATH, HOME and what
  the test adds), in its own process group, ended whatever happens;
* :func:`moved`: a copy of an extraction whose record names a build environment that does
  not exist, as on a machine the FMU was copied to;
* :func:`with_runtime`: a copy of an extraction whose linux64 binary is another build of
  the runtime (``SANITIZERS``: the flags of one built with ASan and UBSan);
* :func:`sanitized_build`: the runtime and a C host built with those flags
  (``SANITIZED_ENVIRONMENT``: what their runs need); :func:`sanitized_runtime` the runtime
  alone, and :func:`asan_preload` the ASan library a Python host preloads to load it;
* ``THREAD_SANITIZER`` (and ``THREAD_SANITIZED_ENVIRONMENT``): the flags of a
  ThreadSanitizer build for :func:`sanitized_build`, and what its runs need.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import pytest
from process_group import run_in_group

from cosim.fmus import native
from fmu_runtime.entry import RECORD_FILE

HOST_SOURCE = Path(__file__).parent / "hosts" / "fmi_host.c"
CLEAN_PATH = "/usr/bin:/bin"
SANITIZERS = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-O1", "-g")
# a sanitized run: leaks are not our finding (CPython's own at exit), malloc seen by ASan,
# no numba (its JIT's memory confuses ASan)
SANITIZED_ENVIRONMENT = {"ASAN_OPTIONS": "detect_leaks=0", "PYTHONMALLOC": "malloc",
                         "AUV_COSIM_NO_JIT": "1"}  # fmt: skip
THREAD_SANITIZER = ("-fsanitize=thread", "-O1", "-g")
# a ThreadSanitizer run: every report printed, the exit code 66 if there was one
THREAD_SANITIZED_ENVIRONMENT = {"TSAN_OPTIONS": "halt_on_error=0 exitcode=66",
                                "PYTHONMALLOC": "malloc", "AUV_COSIM_NO_JIT": "1"}  # fmt: skip


def compiled_host(source: Path, folder: Path) -> Path:
    """The C test host ``source`` compiled into ``folder`` (named after it) with
    ``-Wall -Wextra -Werror``; the test is skipped without ``cc``."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) to build the test host")
    binary = folder / source.stem
    flags = ["-O1", "-g", "-Wall", "-Wextra", "-Werror"]
    subprocess.run([cc, *flags, "-o", binary, source, "-ldl", "-lpthread"], check=True)
    return binary


def run_clean(command: list, home: Path, timeout: float = 900, **extra: str):
    """``command`` in a clean environment (PATH, HOME and ``extra`` only), in its own
    process group, which is ended whatever happens. ``home`` is its working folder too;
    pass the same one (the ``clean_home`` fixture) to share the FMU's numba cache, which
    lives under ``$HOME/.cache``, between runs. Its stdin is /dev/null, its stdout and
    stderr pipes (a Windows CPython under Wine 8 cannot start with a regular file as a
    standard stream: Wine's GetFileInformationByHandle fails on it)."""
    env = {"PATH": CLEAN_PATH, "HOME": str(home), **extra}
    command = [str(part) for part in command]
    return run_in_group(command, timeout=timeout, env=env, cwd=home, stdin=subprocess.DEVNULL)


def moved(extraction: Path, folder: Path) -> Path:
    """A copy of ``extraction`` in ``folder`` whose record names a build Python that is not
    on this machine (everything else the build recorded is kept)."""
    copy = Path(tempfile.mkdtemp(prefix="moved-", dir=folder)) / extraction.name
    shutil.copytree(extraction, copy)
    record = copy / "resources" / RECORD_FILE
    lines = record.read_text().splitlines()
    gone = "/nonexistent/build-environment/bin/python"
    record.write_text(
        "\n".join(f"build_python={gone}" if line.startswith("build_python=") else line
                  for line in lines) + "\n"
    )  # fmt: skip
    return copy


def with_runtime(extraction: Path, runtime: Path, folder: Path) -> Path:
    """A copy of ``extraction`` in ``folder`` whose linux64 binary is ``runtime``."""
    copy = folder / extraction.name
    shutil.copytree(extraction, copy)
    shutil.copyfile(runtime, copy / "binaries" / "linux64" / f"{copy.name.rstrip('0123456789')}.so")
    return copy


def sanitized_build(
    folder: Path, host: Path, flags: Sequence[str] = (), sanitizers: Sequence[str] = SANITIZERS
) -> tuple[Path, Path]:
    """(runtime.so, host executable) in ``folder``: the runtime and the C host ``host``
    (with ``flags`` besides) built with ``sanitizers`` (ASan and UBSan unless told, or
    ``THREAD_SANITIZER``); skips the test without a system C compiler (zig's has no
    sanitizer runtimes here)."""
    runtime = sanitized_runtime(folder, sanitizers)
    executable = folder / host.stem
    command = [*sanitizing_toolchain().command, *sanitizers, *flags, "-o", str(executable),
               str(host), "-ldl", "-lm", "-lpthread"]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    return runtime, executable


def sanitizing_toolchain() -> native.Toolchain:
    """The system C compiler; skips the test without one (zig's has no sanitizer runtimes
    here)."""
    chain = native.toolchain()
    if chain is None or chain.zig:
        pytest.skip("no cc")
    return chain


def sanitized_runtime(folder: Path, sanitizers: Sequence[str] = SANITIZERS) -> Path:
    """``folder``/runtime.so: the runtime built with ``sanitizers`` (ASan and UBSan unless
    told)."""
    runtime = folder / "runtime.so"
    command = native.compile_command(sanitizing_toolchain(), runtime, *sanitizers)
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    return runtime


def asan_preload() -> str:
    """The path of the compiler's ASan runtime, for ``LD_PRELOAD`` in a host that was not
    built with it (a Python interpreter loading the sanitized runtime)."""
    command = [*sanitizing_toolchain().command, "-print-file-name=libasan.so"]
    return subprocess.run(command, capture_output=True, text=True, check=True).stdout.strip()
