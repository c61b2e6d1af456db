"""The one exception type the command line turns into a one-line reason."""

import difflib
from collections.abc import Iterable
from pathlib import Path


class CosimError(Exception):
    """A user-facing failure: bad scenario, failed FMU call, unwritable output, ..."""


def unmade_folder(folder: Path, exc: OSError) -> str:
    """Why ``folder`` could not be made (``mkdir`` raised ``exc``), in a few words."""
    return "it is not a folder" if folder.exists() else exc.strerror or str(exc)


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` naming the one choice closest to a mistyped ``word``
    (difflib's ratio 0.75 or more, letter case aside: a letter or two off, a missing
    ``_``), or ``""`` when none is close or two are equally close (``bs-9``: bs-1, bs-2
    or bs-3?)."""
    by_lower = {choice.lower(): choice for choice in choices}
    close = difflib.get_close_matches(word.lower(), list(by_lower), n=2, cutoff=0.75)
    if not close or (len(close) == 2 and _ratio(word, close[0]) == _ratio(word, close[1])):
        return ""
    return f" (did you mean {by_lower[close[0]]!r}?)"


def _ratio(word: str, choice: str) -> float:
    return difflib.SequenceMatcher(None, word.lower(), choice).ratio()
