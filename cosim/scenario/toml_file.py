"""A TOML file read into its table, or one line saying why not: shared by every reader of
a file a user writes (a scenario: :mod:`cosim.scenario.spec`, a study:
:mod:`cosim.study.spec`), so that both say the same of the same slip.

The problem is said without the file's name (``not valid TOML: ...``, ``not UTF-8 text:
...``, ``cannot read it: ...``); each reader puts its own name for the file before it.
"""

from __future__ import annotations

import codecs
import re
import tomllib
from pathlib import Path
from typing import Any


class UnreadableTomlError(ValueError):
    """A TOML file that cannot be read: the message says why, without the file's name."""


def read_toml_file(path: Path) -> dict[str, Any]:
    """The table of the TOML file ``path``. Raises :class:`UnreadableTomlError`: invalid TOML
    (:func:`loads_toml`), bytes that are no UTF-8 (:func:`not_utf8`) or a file the system
    does not read (missing, a folder, no permission)."""
    try:  # utf-8-sig: a byte-order mark (some Windows editors write one) is dropped
        return loads_toml(path.read_text(encoding="utf-8-sig"))
    except NotTomlError as exc:
        raise UnreadableTomlError(f"not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise UnreadableTomlError(not_utf8(exc)) from None
    except OSError as exc:
        raise UnreadableTomlError(f"cannot read it: {exc}") from None


class NotTomlError(ValueError):
    """A text that is not TOML this reader reads; the message says where and why."""


def loads_toml(text: str) -> dict[str, Any]:
    """The table of a TOML text, as ``tomllib.loads`` reads it. Raises :class:`NotTomlError`
    for invalid TOML, and for arrays or inline tables nested thousands deep (valid TOML,
    but beyond Python's recursion limit: tomllib raised RecursionError, which named
    neither the file nor what was wrong)."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise NotTomlError(f"{exc}{toml_hint(text, str(exc))}") from None
    except RecursionError:
        raise NotTomlError("arrays or inline tables nested too deeply to read") from None


_AT_LINE = re.compile(r"\(at line (\d+), column \d+\)$")
_KEY_VALUE = re.compile(r"^\s*(?P<key>[A-Za-z0-9_.\"'-]+)\s*=\s*(?P<value>[^#]*?)\s*(#.*)?$")
_BARE_WORDS = {"true", "false", "inf", "nan", "+inf", "-inf", "+nan", "-nan"}


def toml_hint(text: str, message: str) -> str:
    """What to write instead, after tomllib's ``message`` on the line of ``text`` it names
    (``: write a decimal point, not a comma: 0.26``), for the slips a first scenario file
    has: a decimal comma, a name not quoted, a unit after a number, a key given twice;
    ``""`` for any other."""
    at = _AT_LINE.search(message)
    lines = text.splitlines()
    if at is None or not 0 < int(at.group(1)) <= len(lines):
        return ""
    line = _KEY_VALUE.match(lines[int(at.group(1)) - 1])
    if line is None:
        return ""
    key, value = line.group("key"), line.group("value")
    if message.startswith("Cannot overwrite a value"):
        return f": {key!r} is given twice in its table; keep one"
    if re.fullmatch(r"[-+]?\d+,\d+", value):
        return f": write a decimal point, not a comma: {value.replace(',', '.')}"
    number_and_unit = re.fullmatch(r"([-+]?[\d.]+(?:[eE][-+]?\d+)?)\s+[A-Za-z/%]+", value)
    if number_and_unit:
        return f": a number stands alone, in SI units (here {number_and_unit.group(1)})"
    if re.fullmatch(r"[A-Za-z_][\w-]*", value) and value.lower() not in _BARE_WORDS:
        return f': a string is quoted: "{value}"'
    return ""


def not_utf8(exc: UnicodeDecodeError) -> str:
    """What is wrong with a file whose bytes UTF-8 refused (``exc``, raised decoding the
    whole file, a byte-order mark dropped), in words a user acts on: ``not UTF-8 text:
    byte 0xf6 at line 2, column 5; save it as UTF-8`` (Latin-1, Windows-1252: an editor's
    "Western European"), or ``not UTF-8 text but UTF-16 (...)`` (Windows' "Unicode")."""
    data = bytes(exc.object)
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return (
            "not UTF-8 text but UTF-16 (it starts with a UTF-16 byte-order mark); save it as UTF-8"
        )
    line = data.count(b"\n", 0, exc.start) + 1
    before = data[data.rfind(b"\n", 0, exc.start) + 1 : exc.start].decode("utf-8", "replace")
    return (
        f"not UTF-8 text: byte 0x{data[exc.start]:02x} at line {line}, column "
        f"{len(before) + 1}; save it as UTF-8"
    )
