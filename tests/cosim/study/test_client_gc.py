"""``auv-cosim sweep`` imports what its client needs and starts its cluster with the
garbage collector off (those imports make ~10^6 objects and no garbage, and the full
collections they set off walked them all again on the way to the first run), and turns it
on again before the runs are sent, so the client collects what their results leave."""

from __future__ import annotations

import ast
import gc
import subprocess
import sys
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest

from cosim.study import collector, runner

SWEEP_IMPORTS_THEN_REPORT = """
import gc, sys
from cosim import cli

def imports(args):  # what the sweep's client imports before its cluster is ready
    import cosim.study.execution, cosim.study.runner, matplotlib.text
    print(repr((gc.isenabled(), [s["collections"] for s in gc.get_stats()])))
    return 0

cli._study = imports
sys.argv = ["auv-cosim", "sweep", "study.toml"]
code = cli.main()
print(repr(gc.isenabled()))
sys.exit(code)
"""


@pytest.mark.slow
def test_the_sweep_command_imports_without_full_collections_and_ends_with_the_collector_on() -> (
    None
):
    done = subprocess.run(
        [sys.executable, "-c", SWEEP_IMPORTS_THEN_REPORT],
        capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    during, after = done.stdout.strip().splitlines()[-2:]
    enabled, collections = ast.literal_eval(during)
    assert not enabled, "the collector ran while the sweep's client imported"
    assert collections[2] == 0, f"full collections while the client imported: {collections}"
    assert ast.literal_eval(after), "the command left the collector off"


@pytest.fixture
def collector_state() -> Iterator[None]:
    """The test process's collector as it was, whatever the test did to it."""
    enabled = gc.isenabled()
    try:
        yield
    finally:
        collector.resume()
        gc.unfreeze()
        if enabled:
            gc.enable()


def test_the_runs_are_sent_with_the_collector_on(
    collector_state: None, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    seen: list[bool] = []

    def execute(*args: Any, **kwargs: Any) -> None:
        seen.append(gc.isenabled())

    monkeypatch.setattr(runner, "execute", execute)
    cluster = runner.Cluster(1, scheduler="tcp://127.0.0.1:1")  # its client is never opened
    with ExitStack() as stack:
        session = runner._Session(cluster, stack)
        session.client = object()  # connected
        collector.pause()
        session.run(None, None, [], lambda run, record: None)  # type: ignore[arg-type]
    assert seen == [True], "a study's runs were sent with the collector still off"
