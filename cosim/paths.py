"""Default locations, relative to the current folder (one definition for the whole
package), and a path as the text a file or a library writing UTF-8 takes."""

import os
from pathlib import Path

DEFAULT_FMU_DIR = Path("build/fmus")  # where the built-in FMUs are built and looked up
RUNS_DIR = Path("runs")  # a run's default folder is RUNS_DIR / <scenario id>
DOCS_DIR = Path("docs")  # the documentation: reproduction.md, dissertation-values.toml


def path_text(path: str | os.PathLike[str]) -> str:
    """``path`` as UTF-8 text: its name's bytes read as UTF-8, a byte that is no UTF-8 as
    a backslash escape (a folder named in Latin-1, ``gr\\xf6sse``).

    Python reads such a byte as a lone surrogate (U+DCF6), which a UTF-8 file or library
    refuses ("surrogates not allowed"); under an ASCII locale (``LANG=C`` with Python's
    UTF-8 mode off) every byte of ``Größe`` is one, and this gives ``Größe`` back."""
    text = os.fspath(path)
    try:
        raw = text.encode("utf-8", "surrogateescape")
    except UnicodeEncodeError:  # a surrogate no byte of a name gives (U+D800)
        return text.encode("utf-8", "backslashreplace").decode("utf-8")
    return raw.decode("utf-8", "backslashreplace")
