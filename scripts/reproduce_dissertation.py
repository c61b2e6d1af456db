"""Regenerate ``docs/reproduction.md`` from any folder: ``auv-cosim reproduce`` with the
repository's ``docs/`` (the claims live in ``cosim/reproduction/``).

    python scripts/reproduce_dissertation.py [--skip-scenarios]
"""

import sys
from pathlib import Path

from cosim.cli import main

DOCS = Path(__file__).resolve().parents[1] / "docs"

if __name__ == "__main__":
    values = DOCS / "dissertation-values.toml"
    sys.exit(main(["reproduce", "--out", str(DOCS), "--values", str(values), *sys.argv[1:]]))
