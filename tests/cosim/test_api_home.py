"""The Python API under a relative HOME: matplotlib's folders stay out of the caller's
working folder, as the command's do, and the caller's environment is left as it was."""

from __future__ import annotations

from pathlib import Path

import pytest
from relative_home import PREAMBLE

RELATIVE_HOME_SWEEP = (
    PREAMBLE
    + """import cosim

if __name__ == "__main__":
    before = dict(os.environ)
    study = {"scenario": "bs-3", "stop_time": 0.2, "grid": {"plant.v_0": [-0.1, -0.05]}}
    cosim.sweep(study, workers=1, out=sys.argv[3], fmu_dir=sys.argv[4])
    import matplotlib

    print(matplotlib.get_cachedir())
    print("environment as it was" if dict(os.environ) == before else "environment changed")
"""
)


@pytest.mark.slow
@pytest.mark.cluster
def test_a_study_from_the_api_under_a_relative_home_writes_no_matplotlib_folder_there(
    run_python, tmp_path: Path, fmu_dir: Path
) -> None:
    """``cosim.sweep(..., out=...)`` with ``HOME=home`` (relative) made
    ``home/.config/matplotlib`` and ``home/.cache/matplotlib/fontlist-*.json`` in the
    caller's working folder as the study drew its figures (the command had been fixed,
    the API not). matplotlib's folder is the one auv-cosim's caches fall back to,
    absolute, for the study only: the caller's environment is as it was."""
    scratch, work, out = tmp_path / "tmp", tmp_path / "work", tmp_path / "study"
    scratch.mkdir()
    work.mkdir()
    done = run_python(RELATIVE_HOME_SWEEP, scratch, work, out, fmu_dir)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (out / "index.html").is_file()
    assert sorted(str(p.relative_to(work)) for p in work.rglob("*")) == []
    cache, environment = done.stdout.splitlines()[-2:]
    assert Path(cache).is_absolute() and Path(cache).is_relative_to(scratch), cache
    assert environment == "environment as it was"
