"""Default locations, relative to the current folder (one definition for the whole
package), and a path as the text a file or a library writing UTF-8 takes."""

import os
from pathlib import Path

DEFAULT_FMU_DIR = Path("build/fmus")  # where the built-in FMUs are built and looked up
RUNS_DIR = Path("runs")  # a run's default folder is RUNS_DIR / <scenario id>
DOCS_DIR = Path("docs")  # the documentation: reproduction.md, dissertation-values.toml


def path_text(path: str | os.PathLike[str]) -> str:
    """``path`` as UTF-8 text: the bytes the file system holds its name in, read as UTF-8,
    a byte that is no UTF-8 as a backslash escape (a folder named in Latin-1, ``gr\\xf6sse``).

    Python reads such a byte as a lone surrogate (U+DCF6), which a UTF-8 file or library
    refuses ("surrogates not allowed"); where Python reads file names as ASCII (``LC_ALL=C``
    with its UTF-8 mode off) every byte of ``Größe`` is one, and where it reads them as
    Latin-1 (``de_DE.ISO-8859-1``) they are ``GrÃ¶Ãe``: both give ``Größe`` back."""
    text = os.fspath(path)
    try:
        raw = os.fsencode(text)
    except UnicodeEncodeError:  # a character the locale names no file with (ü in ASCII)
        return text.encode("utf-8", "backslashreplace").decode("utf-8")
    return raw.decode("utf-8", "backslashreplace")


def undecoded(text: str) -> bool:
    """Whether ``text`` holds bytes Python could not decode (a name's bytes that are no
    UTF-8, read as surrogates; :func:`path_text` shows them), which no UTF-8 file or
    library takes as they are."""
    return any("\ud800" <= c <= "\udfff" for c in text)
