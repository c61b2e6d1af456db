"""The command under environment variables its libraries read, set to values they refuse
(cosim/cli.py): the command's own drawing does not depend on them."""

from __future__ import annotations

import pytest

WITH_BACKEND = """
import os, sys
os.environ["MPLBACKEND"] = sys.argv[1]
sys.argv = ["auv-cosim", *sys.argv[2:]]
from cosim.cli import main

sys.exit(main())
"""


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["garbage", "module://nowhere"])
def test_a_matplotlib_backend_matplotlib_refuses_does_not_stop_a_drawing(
    run_python, tmp_path, backend
):
    """``MPLBACKEND=garbage auv-cosim report RUN`` (and every command that draws) failed:
    "ValueError: Key backend: 'garbage' is not a valid value for backend; supported
    values are [...]", as matplotlib refused to be imported. The command draws PNG files
    off-screen, never a window, so it draws with matplotlib's Agg whatever the variable."""
    out = tmp_path / "portrait"
    done = run_python(WITH_BACKEND, backend, "analyze", "phase-portrait", "--out", out)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (out / "phase_portrait.png").is_file()
