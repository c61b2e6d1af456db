"""The one exception type the command line turns into a one-line reason, and the one-line
form its warnings take."""

import difflib
import logging
import math
import os
import sys
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import cosim.environ_writes as environ_writes
from fmu_runtime.log_text import shortened, without_traceback


class CosimError(Exception):
    """A user-facing failure: bad scenario, failed FMU call, unwritable output, ..."""


@dataclass(frozen=True)
class OptionNames:
    """How a refusal names an option it was given: by the command line's flag
    (``--stop-time -1.0``, :data:`FLAGS`) or by the Python API's keyword
    (``stop_time=-1.0``, :data:`KEYWORDS`), so each caller reads its own words."""

    keywords: bool = False

    def given(self, option: str, value: object) -> str:
        """The option as given: ``--out runs/x`` or ``out='runs/x'``; the folder of a
        resumed run, ``resume``, as ``--resume runs/x`` or ``out='runs/x'``
        (``cosim.resume``'s argument)."""
        if self.keywords:
            shown = os.fspath(value) if isinstance(value, os.PathLike) else value
            return f"{self._keyword(option)}={shown!r}"
        return f"--{option.replace('_', '-')} {value}"

    def option(self, option: str) -> str:
        """The option to give a value to: ``--out`` or ``out=`` (``resume``, the folder of
        a resumed run: ``--resume`` or ``out=``)."""
        return f"{self._keyword(option)}=" if self.keywords else f"--{option.replace('_', '-')}"

    def takes(self, option: str, what: str) -> str:
        """The option with a value of its kind: ``--checkpoint-every SECONDS`` or
        ``checkpoint_every=SECONDS``."""
        return f"{self.option(option)}{'' if self.keywords else ' '}{what}"

    @staticmethod
    def _keyword(option: str) -> str:
        """The API's keyword of a value-taking option: its name, but the folder of a run
        to resume, ``--resume OUT``, which is ``cosim.resume(out)``'s ``out``."""
        return "out" if option == "resume" else option

    def switch(self, option: str) -> str:
        """The option that turns something on: ``--overwrite`` or ``overwrite=True``."""
        return f"{option}=True" if self.keywords else f"--{option.replace('_', '-')}"


FLAGS = OptionNames()  # the command line's
KEYWORDS = OptionNames(keywords=True)  # the Python API's (cosim.api)


def shown(value: object) -> str:
    """``value`` as a refusal shows it: its repr, shortened if long (an int of 400 digits
    as its first 40 characters and how many it has)."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"


def seconds(t: float) -> str:
    """A time (s) as the run's grid has it: the fewest digits that name it to within the
    rounding of a point computed as n h (4 units in the last place: ``57 * 0.01`` is
    0.5700000000000001, named ``0.57``), laid out as Python's repr (``20000.05``, not
    ``%g``'s ``20000``), a whole number without its ``.0``."""
    t = float(t)
    if not math.isfinite(t):
        return repr(t)
    near = 4.0 * math.ulp(t)
    # by hand: no formatter rounds to "within n ulp"; 17 digits always name t exactly
    digits = next(p for p in range(1, 18) if abs(float(f"{t:.{p}g}") - t) <= near)
    return repr(float(f"{t:.{digits}g}")).removesuffix(".0")


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, the noun in the plural unless there is one: "1 finished
    run", "2 finished runs" (``noun``'s plural: an "s" more)."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def plain(value: object) -> object:
    """A numpy bool, integer or floating scalar as the Python bool, int or float of the
    same value (``float(np.float32(-0.1))``), as a given value is checked; any other value
    (an array, a Decimal) as it is."""
    if type(value).__module__ != "numpy":  # numpy not imported for plain values
        return value
    import numpy as np

    if isinstance(value, np.floating):  # float(): .item() keeps a longdouble a longdouble
        return float(value)
    if isinstance(value, np.bool_ | np.integer):
        return value.item()
    return value


def unmade_folder(folder: Path, exc: OSError) -> str:
    """Why ``folder`` could not be made (``mkdir`` raised ``exc``), in a few words."""
    return "it is not a folder" if folder.exists() else exc.strerror or str(exc)


# the C0 and C1 control characters, as Python writes them in a string: \n, \t, \x1b
_CONTROL = {code: ascii(chr(code))[1:-1] for code in (*range(0x20), *range(0x7F, 0xA0))}


def one_line(text: str) -> str:
    """``text`` with its control characters escaped as Python writes them (a line break in
    a file's name as ``\\n``): a refusal naming that file stays one line, and no escape
    sequence of a name reaches the terminal."""
    return text.translate(_CONTROL)


def unencodable(exc: UnicodeEncodeError) -> str | None:
    """What a locale's legacy encoding could not encode (``exc``: a path given to the
    system where Python reads file names as ASCII, ``LC_ALL=C`` with its UTF-8 mode off),
    and the setting that lets it: ``'Größe' holds 'ö', which this locale's encoding
    (ascii) has not: set PYTHONUTF8=1 ...``; None for a UTF codec's refusal (a surrogate:
    bytes of a name that are no UTF-8)."""
    if exc.encoding.lower().replace("_", "-").startswith("utf"):
        return None
    return (
        f"{exc.object!r} holds {exc.object[exc.start]!r}, which this locale's encoding "
        f"({exc.encoding}) has not: set PYTHONUTF8=1 (or a UTF-8 locale, LC_ALL=C.UTF-8)"
    )


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` naming the choice :func:`closest` to a mistyped ``word``,
    or ``""``."""
    choice = closest(word, choices)
    return "" if choice is None else f" (did you mean {choice!r}?)"


def did_you_mean_path(path: Path) -> str:
    """:func:`did_you_mean` for a path that does not exist, among the names in its folder
    (``runs/bs3``: ``runs/bs-3``); ``""`` when that folder cannot be listed."""
    try:  # the path itself is no suggestion (a file given where a folder is expected)
        names = [entry.name for entry in path.parent.iterdir() if entry.name != path.name]
    except (OSError, ValueError):  # ValueError: a NUL in the path
        return ""
    choice = closest(path.name, names)
    return "" if choice is None else f" (did you mean {str(path.with_name(choice))!r}?)"


def relative_to(path: Path) -> str:
    """`` (relative to <working folder>)`` for a relative ``path``, where a refusal names
    it as given, so that the path shows once and its folder too; ``""`` for an absolute
    one (the path as given says where)."""
    return "" if path.is_absolute() else f" (relative to {Path.cwd()})"


def closest(word: str, choices: Iterable[str]) -> str | None:
    """The one choice closest to a mistyped ``word`` (difflib's ratio 0.75 or more, letter
    case aside: a letter or two off, a missing ``_``; or the one that reads the same with
    O for 0 and I or l for 1); None when none is close or two are equally close
    (``bs-9``: bs-1, bs-2 or bs-3?)."""
    by_lower = {choice.lower(): choice for choice in choices if choice != word}
    alike = [c for c in by_lower.values() if _lookalike(c) == _lookalike(word)]
    if len(alike) == 1:  # v_O for v_0: letters that look like digits (too short for difflib)
        return alike[0]
    close = difflib.get_close_matches(word.lower(), list(by_lower), n=2, cutoff=0.75)
    if not close or (len(close) == 2 and _ratio(word, close[0]) == _ratio(word, close[1])):
        return None
    return by_lower[close[0]]


_LOOKALIKES = str.maketrans("oil", "011")  # O for 0, I or l for 1


def _lookalike(word: str) -> str:
    """``word`` with the letters that look like digits read as those digits."""
    return word.lower().translate(_LOOKALIKES)


def _ratio(word: str, choice: str) -> float:
    return difflib.SequenceMatcher(None, word.lower(), choice).ratio()


def one_line_warnings(who: str) -> Callable[..., None]:
    """``warnings.showwarning`` of a process ``who`` names ("auv-cosim run", a study's
    worker): a warning as one line on stderr, "<who>: warning: <message>", as the command's
    errors are (Python's shows the file, the line number and the source line of the code
    that warned: noise to a user; so is a traceback a library's warning holds)."""

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        print(f"{who}: warning: {shortened(without_traceback(str(message)))}", file=sys.stderr)

    return show


class _MatplotlibFolderInOneLine(logging.Filter):
    """matplotlib's two warnings where its folder cannot be written (a ``HOME`` that is
    missing or not the user's: "mkdir -p failed for path ..." and "Matplotlib created a
    temporary cache directory ..."), said as one of the command's warnings naming the
    folder and what to set. Matched by matplotlib's wording; another wording passes as
    matplotlib writes it."""

    def filter(self, record: logging.LogRecord) -> bool:
        text = str(record.msg)
        if text.startswith("mkdir -p failed for path") or text.endswith(
            "is not a writable directory"
        ):
            return False
        args = record.args if isinstance(record.args, tuple) else ()
        if text.startswith("Matplotlib created a temporary cache directory") and len(args) == 2:
            temporary, issue = args  # issue: "the default path (<folder>)", say
            problem = f"matplotlib's folder cannot be written ({issue})"
            if issue == "resolving the home directory":  # Path.home() raised
                problem = "matplotlib has no folder: there is no home folder (HOME unset, "
                problem += "and no passwd entry for this uid)"
            warnings.warn(
                f"{problem}: using a temporary one "
                f"({temporary}, removed at exit), its font cache made again in every "
                "process; set MPLCONFIGDIR (or HOME) to a writable folder",
                RuntimeWarning,
                stacklevel=2,
            )
            return False
        return True


def matplotlib_off_screen() -> None:
    """Have matplotlib draw with its Agg canvas in this process, before it is imported: the
    command's figures are matplotlib Figures saved as PNG files, never a window, so the
    backend a user's ``MPLBACKEND`` names (for plots of their own) is of no use to it, and
    one matplotlib does not know (``MPLBACKEND=garbage``) failed its import and with it
    every command that draws. For the command's own process only: the Python API leaves
    its caller's backend as it is."""
    os.environ["MPLBACKEND"] = "agg"


def matplotlib_folder_absolute(fallback: Callable[[], Path]) -> None:
    """Point matplotlib at the folder ``fallback()`` returns (``MPLCONFIGDIR``, unless the
    user set it) where its own folders would be relative: a relative (or empty) ``HOME``,
    ``XDG_CONFIG_HOME`` or ``XDG_CACHE_HOME``, which matplotlib takes as it is, so that a
    command drawing from another folder made ``<HOME>/.config/matplotlib`` and
    ``<HOME>/.cache/matplotlib`` there. auv-cosim's own caches ignore a relative one
    (:func:`plant_fmu.model.jit.default_cache_dir`); ``fallback`` is called only then.
    Before matplotlib is imported: in the command's own process, or for a study of the
    Python API (``cosim.sweep``, which puts its caller's environment back after it; the
    folder matplotlib resolved stays its folder in that process)."""
    if os.environ.get("MPLCONFIGDIR"):
        return
    home = os.environ.get("HOME")
    xdg = [os.environ.get(name, "") for name in ("XDG_CONFIG_HOME", "XDG_CACHE_HOME")]
    relative = home is not None and not os.path.isabs(home)
    if relative or any(base and not os.path.isabs(base) for base in xdg):
        environ_writes.set_variable("MPLCONFIGDIR", str(fallback()))


def matplotlib_folder_in_one_line() -> None:
    """Have matplotlib's warnings of a folder it cannot write said in one line (with
    :func:`one_line_warnings`), before matplotlib is imported; matplotlib itself is not."""
    logging.getLogger("matplotlib").addFilter(_MatplotlibFolderInOneLine())
