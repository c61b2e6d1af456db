"""The command line's own options, apart from any command."""

import importlib.metadata

import pytest

from cosim.cli import main


def test_version_is_the_installed_packages(capsys: pytest.CaptureFixture[str]) -> None:
    """A user reporting a problem is asked for the version: ``--version`` prints it and
    exits 0 without a command."""
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out == f"auv-cosim {importlib.metadata.version('auv-cosim')}\n"
