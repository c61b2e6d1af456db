"""A run or a study under an address-space limit (``ulimit -v``) too small for it is refused
at once, in one line naming the limit and what to do, leaving nothing behind; a failure for
want of memory is one line naming the limit, never a traceback."""

from __future__ import annotations

import resource
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from process_group import run_in_group

from cosim import limits
from cosim.cli import main

TOO_SMALL = 900 * limits.MB  # where a run failed naming no limit, with tracebacks


def one_line_refusal(done: subprocess.CompletedProcess, start: str) -> str:
    """The one stderr line a command refused with (exit 1), checked to begin with ``start``."""
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(start), lines
    return lines[0]


def _limited(limit: int) -> Callable[[], None]:
    """A preexec function: the child's address space limited to ``limit`` bytes."""

    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    return apply


def _cosim(args: list[str], cwd: Path, limit: int) -> tuple[int, str]:
    """``python -m cosim ARGS`` in ``cwd`` under the address-space ``limit``: its exit code
    and stderr. 90 s at most: a run that hangs in a library's start-up fails the test."""
    done = run_in_group(
        [sys.executable, "-m", "cosim", *args], timeout=90, cwd=cwd, preexec_fn=_limited(limit)
    )
    return done.returncode, done.stderr


def _refused(code: int, err: str, command: str) -> None:
    assert code == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"auv-cosim {command}: the address-space limit"), err
    assert f"{TOO_SMALL // limits.MB} MB (ulimit -v)" in lines[0] and "raise it" in lines[0]


@pytest.mark.slow
def test_a_run_under_too_small_an_address_space_is_refused_naming_the_limit(
    tmp_path: Path, fmu_paths: dict[str, Path]
) -> None:
    """At 900 MB `auv-cosim run bs-3` printed rerun's tracebacks and "RuntimeError: Failed
    to spawn background thread"; at 1700 MB it hung in OpenBLAS's start-up; between, the
    plant FMU said numba's "libllvmlite.so" could not be found."""
    fmu_dir = next(iter(fmu_paths.values())).parent
    args = ["run", "bs-3", "--stop-time", "1", "--fmu-dir", str(fmu_dir), "--out", "x"]
    code, err = _cosim(args, tmp_path, TOO_SMALL)
    _refused(code, err, "run")
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_a_study_under_too_small_an_address_space_is_refused_naming_the_limit(
    tmp_path: Path, fmu_paths: dict[str, Path]
) -> None:
    """At 900 MB `auv-cosim sweep` printed a bare "MemoryError" and then "RuntimeError:
    can't start new thread"."""
    fmu_dir = next(iter(fmu_paths.values())).parent
    study = tmp_path / "s.toml"
    study.write_text('scenario = "bs-3"\nstop_time = 1.0\n[grid]\n"plant.v_0" = [0.1]\n')
    args = ["sweep", "s.toml", "--quiet", "--fmu-dir", str(fmu_dir), "--out", "s"]
    code, err = _cosim(args, tmp_path, TOO_SMALL)
    _refused(code, err, "sweep")
    assert not (tmp_path / "s").exists()


def _few_files(count: int) -> Callable[[], None]:
    """A preexec function: the child may have ``count`` files open (soft and hard)."""

    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_NOFILE, (count, count))

    return apply


@pytest.mark.slow
def test_a_study_with_too_few_open_files_is_refused_naming_the_limit(
    tmp_path: Path, fmu_paths: dict[str, Path]
) -> None:
    """Under `ulimit -n 32` `auv-cosim sweep` printed Dask's tracebacks ("Nanny failed to
    start process", "AttributeError: 'NoneType' object has no attribute 'terminate'")
    before its one line."""
    fmu_dir = next(iter(fmu_paths.values())).parent
    study = tmp_path / "s.toml"
    study.write_text('scenario = "bs-3"\nstop_time = 1.0\n[grid]\n"plant.v_0" = [0.1]\n')
    args = ["sweep", "s.toml", "--quiet", "--fmu-dir", str(fmu_dir), "--out", "s"]
    command = [sys.executable, "-m", "cosim", *args]
    done = run_in_group(command, timeout=90, cwd=tmp_path, preexec_fn=_few_files(32))
    line = one_line_refusal(done, "auv-cosim sweep: the open-files limit of this process, 32")
    assert "(ulimit -n)" in line and "raise it" in line, line
    assert not (tmp_path / "s").exists()


@pytest.mark.slow
@pytest.mark.parametrize("count", [12, 16])
def test_a_recorded_run_with_too_few_open_files_is_refused_naming_the_limit(
    tmp_path: Path, fmu_paths: dict[str, Path], count: int
) -> None:
    """docs/runs.md's `(ulimit -n 16; auv-cosim run bs-3)` failed naming no limit ("cannot
    start the Rerun recording: ...: Too many open files", on two lines), and at 12 rerun-sdk
    panicked with a Rust backtrace (exit -6)."""
    fmu_dir = next(iter(fmu_paths.values())).parent
    args = ["run", "bs-3", "--stop-time", "1", "--fmu-dir", str(fmu_dir), "--out", "x"]
    command = [sys.executable, "-m", "cosim", *args]
    done = run_in_group(command, timeout=90, cwd=tmp_path, preexec_fn=_few_files(count))
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    expected = f"auv-cosim run: the open-files limit of this process, {count} (ulimit -n)"
    assert lines[0].startswith(expected), lines
    assert f"ulimit -n {limits.RUN_OPEN_FILES}" in lines[0], lines
    assert not (tmp_path / "x").exists()


def test_a_soft_open_files_limit_is_raised_to_what_a_study_needs() -> None:
    """A soft limit below the need and a hard one above it: the soft one is raised (as
    `ulimit -Sn` may), nothing refused."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard != resource.RLIM_INFINITY and hard < limits.STUDY_OPEN_FILES:
        pytest.skip("the hard limit of this process is below what a study needs")
    resource.setrlimit(resource.RLIMIT_NOFILE, (limits.STUDY_OPEN_FILES - 8, hard))
    try:
        limits.check_open_files("a study", limits.STUDY_OPEN_FILES)
        assert resource.getrlimit(resource.RLIMIT_NOFILE)[0] >= limits.STUDY_OPEN_FILES
    finally:
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


def _small_files(size: int) -> Callable[[], None]:
    """A preexec function: the child may write files of ``size`` bytes at most."""

    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))

    return apply


@pytest.mark.slow
@pytest.mark.parametrize(
    ("size", "options"), [(64 * 1024, []), (1 << 20, ["--no-rrd"])], ids=["recording", "csv"]
)
def test_a_run_past_the_file_size_limit_names_the_limit(
    tmp_path: Path, fmu_paths: dict[str, Path], size: int, options: list[str]
) -> None:
    """Under `ulimit -f 64` a run said its recording was "File too large (74746695680 bytes
    free on its disk)", as if the disk were full; under `ulimit -f 1024` results.csv was
    "File too large (at t = 25.99 s)", naming no limit. The partial results stay marked
    incomplete."""
    fmu_dir = next(iter(fmu_paths.values())).parent
    args = ["run", "bs-3", "--fmu-dir", str(fmu_dir), "--out", "x", *options]
    command = [sys.executable, "-m", "cosim", *args]
    done = run_in_group(command, timeout=120, cwd=tmp_path, preexec_fn=_small_files(size))
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert "File too large" in last and "bytes free on its disk" not in last, last
    assert f"file-size limit of this process, {size} bytes (ulimit -f)" in last, last
    summary = tmp_path / "x" / "summary.json"
    assert not summary.exists() or '"status": "incomplete"' in summary.read_text()


def _no_network() -> bool:
    """Whether this process may start a command in a network namespace of its own."""
    if shutil.which("unshare") is None:
        return False
    done = run_in_group(["unshare", "-n", "true"], timeout=30)
    return done.returncode == 0


@pytest.mark.slow
def test_a_study_without_loopback_is_refused_naming_it(
    tmp_path: Path, fmu_paths: dict[str, Path]
) -> None:
    """Under `unshare -n` (no loopback up) `auv-cosim sweep` waited 30 s for its local
    cluster, then said "RuntimeError: Cluster failed to start: Timed out trying to connect
    to tcp://127.0.0.1:45563 after 30 s"."""
    if not _no_network():
        pytest.skip("unshare -n is not allowed here")
    fmu_dir = next(iter(fmu_paths.values())).parent
    study = tmp_path / "s.toml"
    study.write_text('scenario = "bs-3"\nstop_time = 1.0\n[grid]\n"plant.v_0" = [0.1]\n')
    args = ["sweep", "s.toml", "--quiet", "--fmu-dir", str(fmu_dir), "--out", "s"]
    command = ["unshare", "-n", sys.executable, "-m", "cosim", *args]
    done = run_in_group(command, timeout=90, cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("auv-cosim sweep: a study's local workers talk over 127.0.0.1")
    assert "ip link set lo up" in lines[0], lines[0]
    assert not (tmp_path / "s").exists()


@pytest.mark.slow
def test_a_study_without_a_writable_dev_shm_is_refused_naming_it(
    tmp_path: Path, fmu_paths: dict[str, Path]
) -> None:
    """With /dev/shm read-only (a container's) `auv-cosim sweep` printed Dask's tracebacks
    ("Nanny failed to start process", "OSError: [Errno 30] Read-only file system") and
    then "RuntimeError: Nanny failed to start.", naming no folder."""
    mount = "mount -t tmpfs -o size=4k,ro tmpfs /dev/shm"
    if (
        shutil.which("unshare") is None
        or run_in_group(["unshare", "-m", "sh", "-c", mount], timeout=30).returncode
    ):
        pytest.skip("cannot mount a read-only /dev/shm of its own here")
    fmu_dir = next(iter(fmu_paths.values())).parent
    study = tmp_path / "s.toml"
    study.write_text('scenario = "bs-3"\nstop_time = 1.0\n[grid]\n"plant.v_0" = [0.1]\n')
    sweep = f"{sys.executable} -m cosim sweep s.toml --quiet --fmu-dir {fmu_dir} --out s"
    command = ["unshare", "-m", "sh", "-c", f"{mount} && exec {sweep}"]
    done = run_in_group(command, timeout=90, cwd=tmp_path)
    line = one_line_refusal(done, "auv-cosim sweep: a study's workers need a semaphore")
    assert "/dev/shm" in line and "Read-only file system" in line, line
    assert not (tmp_path / "s").exists()


def test_out_of_memory_is_one_line_naming_the_limit(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """A MemoryError escaped the command as a traceback (the last line a bare
    "MemoryError")."""

    def starved(*args: object) -> int:
        raise MemoryError

    monkeypatch.setattr("cosim.runner.run_from_cli", starved)
    monkeypatch.setattr(limits, "address_space_limit", lambda: 800 * limits.MB)
    assert main(["run", "bs-3"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("auv-cosim run: out of memory (MemoryError"), err
    assert "address-space limit 800 MB, ulimit -v: raise it" in err
