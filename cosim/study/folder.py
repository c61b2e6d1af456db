"""The study folder: what study it holds (``study.json``), and the kept per-run folders.

``study.json`` records what the table's rows depend on: the study file's settings, the
resolved scenario and the FMUs' content hashes. A new study refuses a folder that already
holds one; ``--resume`` refuses a folder whose study differs (another scenario, other
factors or metrics, rebuilt FMUs), so a table never mixes two studies.

Per-run folders ``runs/<run id>/`` (only with ``keep = "all"`` or ``"failed"``) hold the
scenario the run ran (``scenario.toml``, for ``auv-cosim run``), its ``results.csv`` and
``summary.json`` when it got that far, and ``error.txt`` when it failed.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from cosim.study.spec import StudyError

STUDY_JSON = "study.json"
RUNS_FOLDER = "runs"


def claim(out_dir: Path, identity: Mapping[str, Any], resume: bool, table: str) -> None:
    """Make ``out_dir`` this study's folder, or check it already is (``resume``).
    ``table``: the table's file name (a folder holding one holds a study)."""
    marker = out_dir / STUDY_JSON
    identity = json.loads(json.dumps(identity))  # as it reads back from the file
    if resume:
        if not marker.is_file():
            raise StudyError(f"--resume: {out_dir} holds no study ({STUDY_JSON} is missing)")
        stored = json.loads(marker.read_text(encoding="utf-8"))
        differ = sorted(k for k in {*stored, *identity} if stored.get(k) != identity.get(k))
        if differ:
            raise StudyError(
                f"--resume: {out_dir} holds another study (its {', '.join(differ)} "
                "differ from this one's); give another --out to start this study"
            )
        return
    if marker.exists() or (out_dir / table).exists():
        raise StudyError(
            f"{out_dir} already holds a study: add --resume to continue it, or give another --out"
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    marker.write_text(json.dumps(identity, indent=2) + "\n", encoding="utf-8")


def keep_run(
    out_dir: Path, run_id: str, scenario: str, files: Mapping[str, bytes], error: str | None
) -> Path:
    """Write one run's folder: its scenario, the files it returned, its error."""
    folder = out_dir / RUNS_FOLDER / run_id
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "scenario.toml").write_text(scenario, encoding="utf-8")
    for name, content in files.items():
        (folder / name).write_bytes(content)
    if error is not None:
        (folder / "error.txt").write_text(error + "\n", encoding="utf-8")
    return folder
