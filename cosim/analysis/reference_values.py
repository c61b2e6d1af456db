"""The dissertation's printed numbers (``docs/dissertation-values.toml``), read in one place.

The tests (through ``tests/reference_values.py``) and the reproduction
(``cosim/reproduction/``) compare the model with these numbers. The file is repository
data, not package data, so the caller passes its path.

A value keeps the digits it was printed with: the file's floats are parsed as
:class:`decimal.Decimal`, so ``1.4050`` keeps its four decimals, and
:attr:`Reference.resolution` is one unit of the last printed digit (the tolerance the
reproduction report calls "agrees"). An entry may give another ``tolerance`` (the text's
"within", "slightly larger than", "about") and, when that is wider than the printed
digits, its ``tolerance_reason``.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from cosim.errors import CosimError

Printed = Decimal | list["Printed"]
"""A number as printed, or a (nested) list of them."""


class ReferenceValueError(CosimError, ValueError):
    """The reference-value file is missing, malformed, or an entry lacks what it needs: a
    refusal the command says in one line (a :class:`~cosim.errors.CosimError`), naming the
    file and the entry."""


TOLERANCE_KINDS = ("absolute", "relative", "slightly_above", "at_most")


class References(dict[str, "Reference"]):
    """The entries of one reference-value file by dotted key; a key the file lacks is a
    :class:`ReferenceValueError` naming the key and the file (not a ``KeyError``)."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = path

    def __missing__(self, key: str) -> Reference:
        raise ReferenceValueError(
            f"reference values {str(self.path)!r}: no entry {key!r}, which a claim of "
            "docs/reproduction.md checks"
        )


class _Entry(BaseModel):
    model_config = ConfigDict(extra="forbid", arbitrary_types_allowed=True)

    value: Any
    unit: str | list[str]
    source: str
    description: str
    tolerance: dict[str, float | bool] = {}
    tolerance_reason: str = ""

    @field_validator("tolerance")
    @classmethod
    def _one_kind(cls, value: dict[str, float | bool]) -> dict[str, float | bool]:
        if len(value) != 1 or next(iter(value)) not in TOLERANCE_KINDS:
            raise ValueError(f"expected one of {', '.join(TOLERANCE_KINDS)}, got {value}")
        return value


@dataclass(frozen=True)
class Reference:
    """One printed value with its unit and where the dissertation prints it.

    Attributes:
        key: dotted name in the file, e.g. ``"example_5_1.turn_positive_v"``.
        printed: the number(s) as printed (:class:`~decimal.Decimal`, nested lists).
        unit: SI unit, or one per entry of a vector.
        source: example, figure, table, section or equation number.
        description: what the value is.
        tolerance: how ours is compared with it when not to its printed precision (one
            unit of the last digit): ``{"absolute": x}``, ``{"relative": f}``,
            ``{"slightly_above": x}`` (the text's "slightly larger than") or
            ``{"at_most": True}`` (the text's "within"); empty for the printed precision.
        tolerance_reason: why, when that tolerance is wider than the printed precision.
    """

    key: str
    printed: Printed
    unit: str | tuple[str, ...]
    source: str
    description: str
    tolerance: Mapping[str, float | bool] = field(default_factory=dict)
    tolerance_reason: str = ""

    @property
    def value(self) -> float | np.ndarray:
        """The value as a float, or a float array of the printed shape."""
        if isinstance(self.printed, Decimal):
            return float(self.printed)
        return np.array(_map(self.printed, float), dtype=float)

    @property
    def text(self) -> str | list:
        """The value as printed: a string, or nested lists of strings."""
        return _map(self.printed, str)

    @property
    def resolution(self) -> float | np.ndarray:
        """One unit of the last printed digit (1 for an integer), per entry."""
        if isinstance(self.printed, Decimal):
            return _unit_of_last_digit(self.printed)
        return np.array(_map(self.printed, _unit_of_last_digit), dtype=float)


def load_reference_values(path: Path) -> References:
    """Every entry of the TOML file at ``path``, by dotted key.

    Raises:
        ReferenceValueError: the file cannot be read or parsed, or an entry is not a table
            of ``value`` (numbers, rectangular lists of numbers), ``unit``, ``source`` and
            ``description``; the message names the entry.
    """
    try:
        table = tomllib.loads(Path(path).read_text(encoding="utf-8"), parse_float=Decimal)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ReferenceValueError(f"reference values {str(path)!r}: {exc}") from exc
    references = References(Path(path))
    try:
        _collect(table, prefix="", out=references)
    except ReferenceValueError as exc:
        raise ReferenceValueError(f"reference values {str(path)!r}: {exc}") from None
    return references


def _collect(table: dict[str, Any], prefix: str, out: dict[str, Reference]) -> None:
    """Walk the groups down to the entries, the tables that hold a ``value``."""
    for name, item in table.items():
        key = f"{prefix}{name}"
        if not isinstance(item, dict):
            raise ReferenceValueError(
                f"entry {key!r}: expected a table with value, unit, source and "
                f"description, got {item!r}"
            )
        if "value" not in item:
            _collect(item, prefix=f"{key}.", out=out)
            continue
        try:
            entry = _Entry.model_validate(item)
        except ValidationError as exc:
            problems = "; ".join(
                f"{'.'.join(map(str, err['loc'])) or 'entry'}: {err['msg']}" for err in exc.errors()
            )
            raise ReferenceValueError(f"entry {key!r}: {problems}") from None
        unit = entry.unit if isinstance(entry.unit, str) else tuple(entry.unit)
        out[key] = Reference(
            key,
            _number(entry.value, key),
            unit,
            entry.source,
            entry.description,
            entry.tolerance,
            entry.tolerance_reason,
        )


def _number(value: Any, key: str) -> Printed:
    """``value`` with integers as Decimal; refuses anything but numbers and even lists."""
    if isinstance(value, bool) or not isinstance(value, Decimal | int | list):
        raise ReferenceValueError(f"entry {key!r}: {value!r} is not a number or a list of numbers")
    if not isinstance(value, list):
        if not Decimal(value).is_finite():  # nan, inf: a printed value has a last digit
            raise ReferenceValueError(f"entry {key!r}: {value} is not a finite number")
        return Decimal(value)
    items = [_number(item, key) for item in value]
    if not items or len({np.shape(_map(item, float)) for item in items}) != 1:
        raise ReferenceValueError(f"entry {key!r}: {value!r} is not a non-empty rectangular array")
    return items


def _map(printed: Printed, function: Any) -> Any:
    if isinstance(printed, list):
        return [_map(item, function) for item in printed]
    return function(printed)


def _unit_of_last_digit(number: Decimal) -> float:
    exponent = number.as_tuple().exponent
    if not isinstance(exponent, int):  # "n", "N", "F": NaN or infinity
        raise ValueError(f"printed value {number}: expected a finite number")
    return float(Decimal(1).scaleb(exponent))
