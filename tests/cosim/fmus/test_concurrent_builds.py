"""Builds and validations of one FMU folder from several processes at once (runs started
together on a fresh checkout, a validate during a build): one process builds an FMU, the
others wait for it and use what it wrote. The interleaving is forced: a builder process
stops right after it installed the FMU, before it wrote the hash file beside it, until
the test lets it go; the test's own build or validation runs meanwhile in a thread."""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from process_group import started_in_group

import cosim
from cosim.errors import CosimError
from cosim.fmus import build, reproducible, validation

NAME = "AuvGuidance"  # the FMU the builder process builds

# A build of NAME into argv[1] that stops after installing the FMU, before its hash file:
# it says "installed" and waits for a line on stdin.
PAUSED_BUILDER = """
import sys
from pathlib import Path
from cosim.fmus import build

installed = build._install

def paused(built, target):
    installed(built, target)
    print("installed", flush=True)
    sys.stdin.readline()

build._install = paused
build.build_fmu(sys.argv[2], Path(sys.argv[1]))
print("done", flush=True)
"""


@contextmanager
def paused_builder(out: Path) -> Iterator[Callable[[], None]]:
    """A process building NAME into ``out``, stopped after it installed the FMU; the
    function yielded lets it write the hash file and end, and waits for that."""
    packages = Path(cosim.__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(packages), str(out.parent)])}
    command = [sys.executable, "-c", PAUSED_BUILDER, str(out), NAME]
    with started_in_group(command, stdin=-1, env=env, cwd=out.parent) as proc:
        assert proc.stdout is not None and proc.stdin is not None
        line = proc.stdout.readline()
        assert line == "installed\n", line + proc.stderr.read()

        def finish() -> None:
            proc.stdin.write("go\n")
            proc.stdin.flush()
            assert proc.stdout.readline() == "done\n", proc.stderr.read()

        yield finish


def alongside(
    monkeypatch: pytest.MonkeyPatch, work: Callable[[], Any], finish: Callable[[], None]
) -> dict[str, Any]:
    """Run ``work`` in a thread while the builder is stopped; once the thread waits for the
    builder's lock (or ended without waiting), let the builder finish, then join the
    thread. What ``work`` returned or raised, and whether it waited."""
    waiting = threading.Event()
    monkeypatch.setattr(build, "_waiting", lambda *args: waiting.set(), raising=False)
    outcome: dict[str, Any] = {"waited": False}

    def target() -> None:
        try:
            outcome["value"] = work()
        except Exception as exc:  # reported by the test's assertions
            outcome["error"] = exc

    thread = threading.Thread(target=target)
    thread.start()
    while thread.is_alive() and not waiting.wait(0.05):
        pass
    outcome["waited"] = waiting.is_set()
    finish()
    thread.join()
    return outcome


def _no_rebuild(*args: object) -> None:
    raise AssertionError("built again what the other process had just built")


@pytest.mark.slow
def test_a_build_waits_for_another_processs_build_of_the_same_fmu_and_uses_it(
    monkeypatch, tmp_path
):
    """Runs started together on a fresh FMU folder: the second one to reach an FMU the
    first is installing waits for it and uses that FMU (it neither refuses the FMU as a
    file no build wrote nor builds it again)."""
    out = tmp_path / "fmus"
    monkeypatch.setattr(build, "_run_pythonfmu", _no_rebuild)
    with paused_builder(out) as finish:
        outcome = alongside(monkeypatch, lambda: build.build_fmu(NAME, out), finish)
    assert outcome.get("error") is None, outcome["error"]
    assert outcome["waited"]
    target = out / f"{NAME}.fmu"
    assert outcome["value"] == target
    hashes = build.recorded_hashes(target.with_name(target.name + build.HASH_SUFFIX))
    assert hashes["fmu"] == build.file_hash(target)


@pytest.mark.slow
def test_validate_during_a_build_waits_for_it_and_finds_nothing_wrong(
    monkeypatch, tmp_path, fmu_paths
):
    """`auv-cosim validate` while `auv-cosim build` replaces an out-of-date FMU: it
    checks the new FMU against the hash file written for it, never the new FMU against the
    old hash file (a false "damaged or replaced")."""
    out = tmp_path / "fmus"
    out.mkdir()
    for source in fmu_paths.values():
        (out / source.name).write_bytes(source.read_bytes())
        hash_name = source.name + build.HASH_SUFFIX
        (out / hash_name).write_bytes(source.with_name(hash_name).read_bytes())
    old = out / f"{NAME}.fmu"  # an earlier build from other sources: other bytes
    old.write_bytes(old.read_bytes() + b"an earlier build")
    old.with_name(old.name + build.HASH_SUFFIX).write_text(
        f"source 0\nfmu {build.file_hash(old)}\ndate {reproducible.stamp()}\n"
    )
    monkeypatch.setattr(validation, "validate_fmus", lambda paths: [])  # no smoke run
    with paused_builder(out) as finish:
        outcome = alongside(monkeypatch, lambda: validation.validate_folder(out), finish)
    assert outcome.get("error") is None, outcome["error"]
    assert outcome["value"] == []
    assert outcome["waited"]


def test_a_lock_file_planted_as_a_link_is_refused_and_its_target_left_alone(tmp_path):
    """The build's lock file sits in the FMU folder under a name anyone can predict: a
    symbolic link planted there is refused, naming it, and the file it names is not
    truncated by the build opening it."""
    out = tmp_path / "fmus"
    out.mkdir()
    victim = tmp_path / "notes.txt"
    victim.write_text("keep me\n")
    (out / f".{NAME}.fmu.lock").symlink_to(victim)
    with pytest.raises(CosimError, match=rf"\.{NAME}\.fmu\.lock is a symbolic link"):
        build.build_fmu(NAME, out)
    assert victim.read_text() == "keep me\n"
