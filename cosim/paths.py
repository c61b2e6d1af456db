"""Default locations, relative to the current folder (one definition for the whole package)."""

from pathlib import Path

DEFAULT_FMU_DIR = Path("build/fmus")  # where the built-in FMUs are built and looked up
RUNS_DIR = Path("runs")  # a run's default folder is RUNS_DIR / <scenario id>
DOCS_DIR = Path("docs")  # the documentation: reproduction.md, dissertation-values.toml
