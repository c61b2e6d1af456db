"""The Python API used carelessly: values of odd types where a number or path is expected,
a returned scenario used as a set member or a dict key, a progress bar with no stderr.
Each is taken as documented or refused in one typed line naming it (docs/api.md, Errors)."""

from __future__ import annotations

import os
import sys
from decimal import Decimal
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.errors import CosimError
from cosim.scenario.checks import ScenarioError


class _Fspath(os.PathLike):  # type: ignore[type-arg]
    """An os.PathLike whose ``__fspath__`` gives ``value``, as a careless one may."""

    def __init__(self, value: object) -> None:
        self.value = value

    def __fspath__(self) -> str:
        return self.value  # type: ignore[return-value]

    def __repr__(self) -> str:
        return f"_Fspath({self.value!r})"


def test_a_nul_byte_in_a_file_start_value_of_with_start_is_a_scenario_error(
    fmu_dir: Path,
) -> None:
    """``with_start({"plant.vehicle": "a\\0.toml"})`` raised ValueError "embedded null
    byte" from posixpath, past ``except CosimError``; ``cosim.run(start=...)`` refused the
    same value in one line."""
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError) as raised:
        scenario.with_start({"plant.vehicle": "my\0vehicle.toml"})
    message = str(raised.value)
    assert "'plant.vehicle'" in message and "NUL" in message and "\n" not in message, message


def test_a_loaded_scenario_hashes_as_it_compares(fmu_dir: Path) -> None:
    """A loaded scenario compares by value but ``hash(scenario)`` raised "unhashable type:
    'ReadOnly'" (a class inside the package): no set of scenarios, no dict keyed by them,
    no ``functools.cache`` over a function taking one. Equal scenarios hash alike."""
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    again = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    other = scenario.with_start({"plant.v_0": 0.05})
    assert scenario == again and hash(scenario) == hash(again)
    assert len({scenario, again, other}) == 2
    assert {scenario: "a"}[again] == "a"


def test_a_progress_bar_without_stderr_runs_without_one(
    fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where Python has no stderr (``pythonw`` on Windows, a service, an embedding GUI:
    ``sys.stderr`` is None) ``cosim.run(..., progress=True)`` raised AttributeError
    "'NoneType' object has no attribute 'write'" from inside tqdm; the run goes on with no
    bar, as it does with nowhere to show one."""
    monkeypatch.setattr(sys, "stderr", None)
    run = cosim.run("bs-3", stop_time=0.05, progress=True, fmu_dir=fmu_dir)
    assert run.complete and len(run.results) == 6


@pytest.mark.parametrize(
    ("value", "named"),
    [
        (_Fspath(b"bs-3"), "expected a str or pathlib.Path (its __fspath__ gave bytes)"),
        (_Fspath(3), "expected a str or pathlib.Path (its __fspath__ gave int)"),
    ],
    ids=["bytes", "int"],
)
def test_a_path_like_giving_no_text_is_refused_naming_what_it_gave(
    value: object, named: str
) -> None:
    """An os.PathLike whose ``__fspath__`` gives bytes was refused as "expected a path
    without a NUL byte" (it held none), and one giving an int raised os.fspath's
    TypeError."""
    with pytest.raises(CosimError) as raised:
        cosim.run(value, stop_time=0.1)  # type: ignore[arg-type]
    message = str(raised.value)
    assert message.startswith(f"scenario={value!r}: {named}"), message


def test_a_numpy_long_double_counts_as_its_float(fmu_dir: Path) -> None:
    """``np.longdouble`` is a numpy floating scalar, which docs/api.md says counts as its
    Python value; ``.item()`` gives it back as a longdouble, so ``stop_time`` and a start
    value of one were refused as "expected a number"."""
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    started = scenario.with_start({"plant.v_0": np.longdouble("0.05")})
    assert started.instances["plant"].start["v_0"] == 0.05
    shorter = scenario.with_overrides(stop_time=np.longdouble(2))
    assert shorter.stop_time == 2.0 and type(shorter.stop_time) is float


WITH_OVERRIDES = [
    ({"stop_time": Decimal("10")}, "stop_time=Decimal('10'): expected a number of seconds"),
    ({"stop_time": Fraction(10)}, "stop_time=Fraction(10, 1): expected a number of seconds"),
    ({"stop_time": np.array(10.0)}, "stop_time=array(10.): expected a number of seconds"),
    ({"stop_time": True}, "stop_time=True: expected a number of seconds"),
    ({"stop_time": "10 s"}, "stop_time='10 s': expected a number of seconds"),
    ({"step": 10**400}, "step=1000000000000000000000000000000000000000... (401 characters): "),
    ({"tolerance": Decimal("0.01")}, "tolerance=Decimal('0.01'): expected a finite number"),
    ({"algorithm": b"jacobi"}, "algorithm=b'jacobi': expected one of 'jacobi', "),
    ({"extrapolation": ["linear"]}, "extrapolation=['linear']: expected one of 'none', "),
    ({"error_estimate": "double"}, "error_estimate='double': expected one of 'extrapolation', "),
]


@pytest.mark.parametrize(("overrides", "named"), WITH_OVERRIDES)
def test_with_overrides_takes_the_values_cosim_run_takes_and_refuses_the_others(
    overrides: dict, named: str, fmu_dir: Path
) -> None:
    """docs/api.md says every value given to ``.with_overrides`` is checked, its type
    included, as ``cosim.run`` checks it; a Decimal, a Fraction or a 0-d array was taken
    for ``stop_time`` (``cosim.run`` refuses them), ``True`` and bytes were refused in
    pydantic's words ("Input should be a valid number"), and an int of 400 digits in a
    line of 950 characters. Now one ScenarioError line naming the keyword."""
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError) as raised:
        scenario.with_overrides(**overrides)
    message = str(raised.value)
    assert message.startswith(named) and "\n" not in message and len(message) < 300, message
    if "error_estimate" not in overrides:  # a key of with_overrides only
        with pytest.raises(CosimError) as ran:
            cosim.run(scenario, **overrides)
        assert str(ran.value) == message, "cosim.run refuses it in other words"


def test_a_run_whose_summary_the_caller_changed_still_shows_itself(fmu_dir: Path) -> None:
    """``run.summary`` is the caller's dict: a script that popped ``complete`` from it (to
    dump the rest) or set ``coupling`` to None made ``repr(run)`` (a notebook showing the
    run) and ``run.complete`` raise KeyError, and ``run.coupling_error`` AttributeError."""
    run = cosim.run("bs-3", stop_time=0.05, fmu_dir=fmu_dir)
    run.summary.pop("complete")
    run.summary["coupling"] = None
    assert repr(run).startswith("Run(scenario='bs-3', complete=False, results=<6 rows")
    assert run.complete is False and run.coupling_error is None


def test_a_folder_under_the_home_folder_is_not_made_in_the_working_folder(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``out="~/runs/bs-3"`` made a folder named ``~`` in the working folder (Python does
    not expand it; a later ``rm -rf ~`` of it in a shell removes the home folder). A path
    of the API starting with ``~`` is the home folder's, as pandas' paths are."""
    home, work = tmp_path / "home", tmp_path / "work"
    home.mkdir()
    work.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(work)
    run = cosim.run("bs-3", stop_time=0.05, out="~/runs/bs-3", recording=False, fmu_dir=fmu_dir)
    assert run.out_dir == home / "runs" / "bs-3" and (run.out_dir / "results.csv").is_file()
    assert list(work.iterdir()) == []


def test_numpy_bools_count_as_their_python_value_for_the_switches(fmu_dir: Path) -> None:
    """A switch computed with numpy (``check_step=errors.any()``) is an ``np.True_``, which
    was refused as "check_step=np.True_: expected True or False"; a numpy bool counts as
    its Python value, as a numpy number does for a time."""
    run = cosim.run(
        "bs-3",
        stop_time=0.05,
        fmu_dir=fmu_dir,
        check_step=np.bool_(False),
        progress=np.bool_(False),
        recording=np.bool_(True),
        overwrite=np.bool_(False),
    )
    assert run.complete and run.coupling_error is None


def test_resume_takes_a_numpy_false_recording_as_false(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``cosim.resume(out, recording=np.False_)`` must write no recording, as
    ``recording=False`` does (not record as the checkpointed run did)."""
    import cosim.runner

    given = []

    def resumed(folder: Path, options: object) -> None:
        given.append(options)
        raise CosimError("stop here")

    monkeypatch.setattr(cosim.runner, "resume_run", resumed)
    for recording in (False, np.bool_(False)):
        with pytest.raises(CosimError, match="stop here"):
            cosim.resume(tmp_path, recording=recording, fmu_dir=fmu_dir)  # type: ignore[arg-type]
    assert given[0] == given[1]


def test_a_tilde_path_with_no_home_folder_to_expand_to_is_refused(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``out="~nosuchuser/runs"`` (a user that does not exist, or ``~`` where neither
    HOME nor the password file gives a home folder) is left as it is by expanduser: the
    run made a folder named ``~nosuchuser`` in the working folder, the one thing a path
    starting with ``~`` must not do (docs/api.md). It is refused in one line naming it."""
    monkeypatch.chdir(tmp_path)
    bad = "~no-such-user-of-auv-cosim/runs"
    with pytest.raises(CosimError) as refused:
        cosim.run("bs-3", stop_time=0.05, out=bad, recording=False, fmu_dir=fmu_dir)
    assert str(refused.value).startswith(f"out={bad!r}: no home folder for '~no-such-user"), str(
        refused.value
    )
    assert list(tmp_path.iterdir()) == []
