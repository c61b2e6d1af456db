"""The run report's figures as matplotlib draws them, for tests that read their lines and
labels instead of the saved pictures."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest


def kept_figures(run: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    """The report's figures of ``run`` as matplotlib objects, by file name (each saved as
    an empty file for the report to move)."""
    from cosim.viz import report

    kept = {}

    def keep(fig: Any, path: Path) -> Path:
        kept[path.name] = fig
        path.touch()
        return path

    monkeypatch.setattr(report, "_save", keep)
    report.write_report(run)
    return kept
