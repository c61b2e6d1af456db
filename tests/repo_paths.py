"""Where the tests find the repository's files, whatever folder a test module lives in."""

from pathlib import Path

TESTS = Path(__file__).resolve().parent  # tests/
ROOT = TESTS.parent  # the repository
TEST_FMUS = TESTS / "fmus"  # pythonfmu scripts of the master tests' own FMUs
