"""Ctrl-C at any moment of ``auv-cosim run``'s start: exit 130 with one line on stderr, no
traceback, nothing left running, never a Ctrl-C lost (the run going on to its end)."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest
from process_group import as_in_a_terminal, group_ended, run_in_group, started_in_group

# ``auv-cosim`` as its installed script starts it (``from cosim.cli import main``), which
# does ACTION as the module named MODULE is first imported: "kill", a Ctrl-C sent to itself
# (a moment of the start chosen by name, the same on every machine, however loaded);
# "mark", "started" written on stdout (cosim.errors: the command's own module has started
# to run, past the interpreter's start and the script's first lines, out of its reach)
_LAUNCHER = """
import importlib.abc, os, signal, sys

ACTION, MODULE = sys.argv.pop(1), sys.argv.pop(1)


class Trip(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name == MODULE:
            sys.meta_path.remove(self)
            if ACTION == "kill":
                os.kill(os.getpid(), signal.SIGINT)
            else:
                sys.stdout.write("started\\n")
                sys.stdout.flush()
        return None


sys.meta_path.insert(0, Trip())
sys.argv[0] = "auv-cosim"
from cosim.cli import main

sys.exit(main())
"""


# ``auv-cosim`` as its installed script starts it, which sends itself a Ctrl-C as the body
# of cosim/cli.py reaches the first statement starting with TEXT (past its imports)
_AT_STATEMENT_LAUNCHER = """
import importlib.util, os, signal, sys

TEXT = sys.argv.pop(1)
CLI = importlib.util.find_spec("cosim.cli").origin
with open(CLI, encoding="utf-8") as source:
    LINE = next(n for n, line in enumerate(source, 1) if line.startswith(TEXT))


def in_module(frame, event, arg):
    if event == "line" and frame.f_lineno == LINE:
        os.kill(os.getpid(), signal.SIGINT)
        return None
    return in_module


def calls(frame, event, arg):
    if frame.f_code.co_filename == CLI and frame.f_code.co_name == "<module>":
        return in_module
    return None


sys.settrace(calls)
sys.argv[0] = "auv-cosim"
from cosim.cli import main

sys.settrace(None)
sys.exit(main())
"""


def _run_args(fmu_dir: Path, out: Path) -> list[str]:
    return ["run", "bs-3", "--stop-time", "20000", "--no-rrd", "--quiet", "--fmu-dir", str(fmu_dir),
            "--out", str(out)]  # fmt: skip


def _assert_interrupted(returncode: int, stderr: str) -> None:
    lines = stderr.splitlines()
    assert returncode == 130, stderr
    assert len(lines) == 1 and lines[0].startswith("auv-cosim"), stderr
    assert "interrupted" in lines[0], stderr


@pytest.mark.slow
@pytest.mark.parametrize(
    "module",
    [
        "cosim.errors",  # the command's own module imported by the script
        "cosim.engine.signals",  # imported as the command starts holding the stop signals
        "cosim.runner",  # the run's modules imported, after the arguments were read
        "fmpy",  # the FMUs loaded
    ],
)
def test_ctrl_c_while_the_command_starts_ends_it_in_one_line(
    module: str, fmu_dir: Path, tmp_path: Path
) -> None:
    """A Ctrl-C while the command imports its modules printed a KeyboardInterrupt traceback
    from inside the import (a death by SIGINT), and one after its arguments were read but
    before the run caught signals was ignored: the run went on to its end. One during the
    import of the module that holds the stop signals, past the arguments' reading, died by
    SIGINT with a traceback too (seen under load as a Ctrl-C 0.1 s into the start)."""
    command = [sys.executable, "-c", _LAUNCHER, "kill", module,
               *_run_args(fmu_dir, tmp_path / "run")]  # fmt: skip
    done = run_in_group(command, timeout=300, preexec_fn=as_in_a_terminal, cwd=tmp_path)
    _assert_interrupted(done.returncode, done.stderr)
    assert not (tmp_path / "run" / "results.csv").exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    "statement",
    [
        "FMU_DIR_HELP =",  # the first statement past the imports
        "_NEGATIVE_NUMBER =",  # a pattern compiled (Python 3.13 took 50 ms to come here)
        "def main(",  # the module's last definitions
    ],
)
def test_ctrl_c_while_the_commands_module_defines_its_names_ends_it_in_one_line(
    statement: str, fmu_dir: Path, tmp_path: Path
) -> None:
    """A Ctrl-C past the command's imports, while cosim/cli.py compiled its patterns and
    defined its functions, printed a KeyboardInterrupt traceback from re's parser and died
    by SIGINT (Python 3.13 came to these statements within a Ctrl-C 50 ms into the start)."""
    command = [sys.executable, "-c", _AT_STATEMENT_LAUNCHER, statement,
               *_run_args(fmu_dir, tmp_path / "run")]  # fmt: skip
    done = run_in_group(command, timeout=300, preexec_fn=as_in_a_terminal, cwd=tmp_path)
    _assert_interrupted(done.returncode, done.stderr)
    assert not (tmp_path / "run" / "results.csv").exists()


@pytest.mark.slow
@pytest.mark.parametrize("after", [0.0, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0])
def test_ctrl_c_at_any_time_of_the_start(after: float, fmu_dir: Path, tmp_path: Path) -> None:
    """Ctrl-C ``after`` s after the command's module started (the command takes over 2 s to
    start the run): it ends on it, exit 130 with one line, and nothing it started goes on
    running."""
    command = [sys.executable, "-c", _LAUNCHER, "mark", "cosim.errors",
               *_run_args(fmu_dir, tmp_path / "run")]  # fmt: skip
    with started_in_group(command, preexec_fn=as_in_a_terminal, cwd=tmp_path) as proc:
        assert proc.stdout is not None
        assert proc.stdout.readline() == "started\n"
        time.sleep(after)
        os.kill(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=300)
        _assert_interrupted(proc.returncode, stderr)
        assert group_ended(proc.pid), "a process of the command's group went on running"
