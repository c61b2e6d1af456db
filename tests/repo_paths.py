"""Where the tests find the repository's files, whatever folder a test module lives in."""

import importlib
import sys
from pathlib import Path
from types import ModuleType

TESTS = Path(__file__).resolve().parent  # tests/
ROOT = TESTS.parent  # the repository
TEST_FMUS = TESTS / "fmus"  # pythonfmu scripts of the master tests' own FMUs


def script_module(name: str) -> ModuleType:
    """The module of ``scripts/<name>.py``, imported (scripts/ is no package)."""
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(ROOT / "scripts"))
