"""Read a vehicle parameter file's TOML text, on every Python an FMU may run in.

On Python >= 3.11 the standard library's ``tomllib`` reads it. An FMU's host may be an
older CPython (3.9 and 3.10 have no ``tomllib``) holding only the standard library and
numpy, where the built-in sets must still load. There a reader written here takes the
subset of TOML a vehicle file needs (a file's keys are numbers and a name and a
description, grouped by tables): comments, blank lines, ``[table]`` headers and
``key = value`` lines whose value is a number (decimal integer or float, ``inf``,
``nan``), a one-line string (``"..."`` with TOML's escapes, or ``'...'``) or a boolean.
Anything else is refused with the line and what is allowed (on such a host, write the
file in that subset or run Python >= 3.11). The two readers agree on every file of the
subset (``tests/plant_fmu/model/test_vehicle_toml.py``).
"""

from __future__ import annotations

import re
import sys
from typing import Any


class VehicleTomlError(ValueError):
    """The text is not TOML this Python can read (the message says where and why)."""


def loads(text: str) -> dict[str, Any]:
    """The table of a TOML text: ``tomllib.loads`` on Python >= 3.11, else
    :func:`loads_subset`.

    Raises:
        VehicleTomlError: the text is not valid TOML, or nested too deeply for Python's
            recursion limit (or, below Python 3.11, not in the subset).
    """
    if sys.version_info >= (3, 11):
        import tomllib  # standard library from 3.11 on (not in an FMU's 3.9 host)

        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise VehicleTomlError(f"not valid TOML: {exc}") from None
        except RecursionError:  # valid TOML, thousands of arrays deep
            raise VehicleTomlError(
                "not valid TOML: arrays or inline tables nested too deeply to read"
            ) from None
    return loads_subset(text)


_KEY = r"[A-Za-z0-9_-]+"
_LINE = re.compile(
    rf"\s*(?:\[\s*(?P<table>{_KEY})\s*\]"
    rf"|(?P<key>{_KEY})\s*=\s*(?P<value>\"(?:[^\"\\]|\\.)*\"|'[^']*'|[^\s#\"'][^\s#]*))?"
    r"\s*(?:#.*)?"
)
_DIGITS = r"(?:0|[1-9](?:_?[0-9])*)"
_INTEGER = re.compile(rf"[+-]?{_DIGITS}")
_FLOAT = re.compile(
    rf"[+-]?(?:{_DIGITS}(?:\.[0-9](?:_?[0-9])*)?(?:[eE][+-]?[0-9](?:_?[0-9])*)?|inf|nan)"
)
_ESCAPES = {"b": "\b", "t": "\t", "n": "\n", "f": "\f", "r": "\r", '"': '"', "\\": "\\"}
_ESCAPE = re.compile(r"\\(?:u([0-9A-Fa-f]{4})|U([0-9A-Fa-f]{8})|(.))")
_SUBSET = (
    "[table] headers and key = value lines whose value is a decimal number, a one-line "
    "string or true/false (Python >= 3.11 reads any TOML)"
)


def loads_subset(text: str) -> dict[str, Any]:
    """The table of a TOML text in the subset of the module docstring.

    Raises:
        VehicleTomlError: naming the line and what the subset allows.
    """
    document: dict[str, Any] = {}
    table = document
    for number, line in enumerate(text.split("\n"), start=1):  # TOML's line breaks only
        line = line[:-1] if line.endswith("\r") else line
        match = _LINE.fullmatch(line)
        if match is None:
            where = f"line {number} ({line.strip()!r})"
            raise VehicleTomlError(f"{where} is not one this Python reads: expected {_SUBSET}")
        if match["table"] is not None:
            if match["table"] in document:
                raise VehicleTomlError(f"line {number}: table [{match['table']}] is defined twice")
            table = document[match["table"]] = {}
        elif match["key"] is not None:
            if match["key"] in table:
                raise VehicleTomlError(f"line {number}: key {match['key']!r} is defined twice")
            try:
                table[match["key"]] = _value(match["value"])
            except ValueError:
                raise VehicleTomlError(
                    f"line {number} ({line.strip()!r}): the value {match['value']!r} is not one "
                    f"this Python reads: expected {_SUBSET}"
                ) from None
    return document


def _value(token: str) -> Any:
    """The value of one token; ValueError if it is outside the subset."""
    if token.startswith('"'):
        return _ESCAPE.sub(_unescape, token[1:-1])
    if token.startswith("'"):
        return token[1:-1]
    if token in ("true", "false"):
        return token == "true"
    if _INTEGER.fullmatch(token):
        return int(token.replace("_", ""))
    if _FLOAT.fullmatch(token):
        return float(token.replace("_", ""))
    raise ValueError(token)


def _unescape(match: re.Match[str]) -> str:
    code = match[1] or match[2]
    if code is not None:
        return chr(int(code, 16))
    if match[3] in _ESCAPES:
        return _ESCAPES[match[3]]
    raise ValueError(match[0])
