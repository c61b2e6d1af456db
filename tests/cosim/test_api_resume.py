"""The Python API's checkpoints: ``cosim.run(..., checkpoint_every=)`` and
``cosim.resume(out)`` do what ``auv-cosim run --checkpoint-every`` and ``--resume`` do,
and their refusals name the keywords a caller gave, not the command line's flags."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from killed_runs import kill_after_checkpoint

import cosim
from cosim.errors import CosimError
from cosim.outputs.checkpoint_file import CHECKPOINT_FILE

STOP_S = 300.0  # long enough for the kill to land between the first checkpoint and the end


def test_checkpoints_without_a_folder_are_refused_naming_the_keyword(fmu_dir: Path) -> None:
    with pytest.raises(CosimError, match=r"^checkpoint_every=0\.2: needs out= "):
        cosim.run("bs-3", stop_time=0.5, checkpoint_every=0.2, fmu_dir=fmu_dir)


@pytest.mark.parametrize("every", [0, -1.0, float("nan"), "10"])
def test_a_bad_checkpoint_interval_is_refused_naming_it(
    fmu_dir: Path, tmp_path: Path, every: object
) -> None:
    with pytest.raises(CosimError, match=r"^checkpoint_every="):
        cosim.run("bs-3", stop_time=0.5, checkpoint_every=every, out=tmp_path / "r",
                  fmu_dir=fmu_dir)  # type: ignore[arg-type]  # fmt: skip
    assert not (tmp_path / "r").exists()


def test_resuming_a_folder_without_a_checkpoint_names_the_keywords(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """cosim.resume's folder is its ``out``: the refusal named ``resume=`` (the command
    line's ``--resume`` as a keyword cosim.resume has not) and said ``checkpoint_every=
    SECONDS`` with a space inside the keyword's value."""
    out = tmp_path / "run"
    cosim.run("bs-3", stop_time=0.2, out=out, recording=False, fmu_dir=fmu_dir)
    with pytest.raises(CosimError) as refused:
        cosim.resume(out, fmu_dir=fmu_dir)
    assert str(refused.value) == (
        f"out={str(out)!r}: no {CHECKPOINT_FILE} there (run with checkpoint_every=SECONDS "
        "to write one)"
    )


def test_a_complete_run_is_not_resumed(fmu_dir: Path, tmp_path: Path) -> None:
    """Refused naming the folder as cosim.resume's ``out``, not as ``resume=``."""
    out = tmp_path / "run"
    run = cosim.run("bs-3", stop_time=0.5, out=out, recording=False, checkpoint_every=0.2,
                    fmu_dir=fmu_dir)  # fmt: skip
    assert run.complete and (out / CHECKPOINT_FILE).is_file()
    with pytest.raises(CosimError) as refused:
        cosim.resume(out, fmu_dir=fmu_dir)
    assert str(refused.value) == f"out={str(out)!r}: the run there is complete: nothing to resume"


def test_resuming_a_folder_without_a_run_names_out(fmu_dir: Path, tmp_path: Path) -> None:
    """A folder holding no run is refused naming cosim.resume's ``out``."""
    with pytest.raises(CosimError) as refused:
        cosim.resume(tmp_path, fmu_dir=fmu_dir)
    assert str(refused.value).startswith(f"out={str(tmp_path)!r}: no run there ("), refused.value


@pytest.mark.slow
def test_a_killed_api_run_resumed_gives_the_uninterrupted_results(
    fmu_dir: Path, tmp_path: Path
) -> None:
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    options = f"stop_time={STOP_S}, recording=False, fmu_dir={str(fmu_dir)!r}"
    cosim.run("bs-3", out=whole, stop_time=STOP_S, recording=False, fmu_dir=fmu_dir)
    code = f"import cosim; cosim.run('bs-3', out={str(killed)!r}, checkpoint_every=10, {options})"
    assert kill_after_checkpoint([sys.executable, "-c", code], killed) != 0
    resumed = cosim.resume(killed, recording=False, fmu_dir=fmu_dir)
    assert resumed.complete
    assert (killed / "results.csv").read_bytes() == (whole / "results.csv").read_bytes()
    assert resumed.results.index[-1] == pytest.approx(STOP_S)
