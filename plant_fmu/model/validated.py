"""Frozen records whose fields are checked when one is made: the vehicle parameter sets
(:class:`plant_fmu.model.parameters.VehicleParameters`) and the controllers'
configurations (the autopilot's and the guidance's FMU parameter lists).

Why by hand and not pydantic: these classes ship inside the FMUs, and an FMU's host Python
may hold nothing but the standard library and numpy (CPython >= 3.9); pydantic is not
there. (``cosim`` keeps pydantic for its own files.)

A record is a frozen dataclass deriving from :class:`CheckedRecord` whose fields are
declared with :func:`checked_field` (range, description, unit, an extra check). Making one,
by its constructor, :meth:`CheckedRecord.from_mapping` or :meth:`CheckedRecord.replace`,
converts and checks every field, then the record's checks across fields
(:meth:`CheckedRecord._check_record`), and raises the record's own error type (a
``ValueError``) with every problem in one line, each naming the field, the bad value and
what is allowed. Field types: ``float`` (any finite real number, an ``int`` included;
stored as float), ``int`` (a whole number), ``bool`` and ``str``.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import typing
from collections.abc import Callable, Mapping
from typing import Any, ClassVar, TypeVar

import numpy as np

_SPEC = "checked_field"  # the key of a field's FieldSpec in its dataclass metadata
# a FieldSpec's quantity for a natural frequency in rad/s (Modelica's SI name): no turn rate
ANGULAR_FREQUENCY = "AngularFrequency"


class _Required:
    """The default of a field that has none (a dataclass needs one on every field after
    the first field with a default, and Python 3.9 has no ``kw_only``)."""

    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()


@dataclasses.dataclass(frozen=True)
class FieldSpec:
    """What a field allows and how it is described.

    ``gt``/``ge``/``lt``/``le`` bound a number (exclusive/inclusive), ``min_length`` a
    string; ``check(value)`` raises ``ValueError`` saying what is expected; its message
    stands alone (it names the field and the value itself) if ``standalone``.
    ``quantity``: what the number is, where its unit leaves it open (FMI 2.0's
    ``quantity``, 2.2.7: ``"AngularFrequency"`` for a natural frequency in rad/s, not a
    turn rate); "" where the unit says it.
    """

    description: str
    unit: str = ""
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    min_length: int | None = None
    check: Callable[[Any], object] | None = None
    standalone: bool = False
    quantity: str = ""


def checked_field(
    default: Any = REQUIRED,
    *,
    description: str,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    min_length: int | None = None,
    check: Callable[[Any], object] | None = None,
    standalone: bool = False,
    quantity: str = "",
) -> Any:
    """A dataclass field of a :class:`CheckedRecord` (no ``default``: the field is
    required). Keyword arguments as :class:`FieldSpec`'s."""
    spec = FieldSpec(description, unit, gt, ge, lt, le, min_length, check, standalone, quantity)
    return dataclasses.field(default=default, metadata={_SPEC: spec})


@dataclasses.dataclass(frozen=True)
class FieldInfo:
    """A field of a record: its name, type (``float``, ``int``, ``bool`` or ``str``),
    default (:data:`REQUIRED` if none) and :class:`FieldSpec`."""

    name: str
    kind: type
    default: Any
    spec: FieldSpec

    @property
    def description(self) -> str:
        return self.spec.description

    @property
    def unit(self) -> str:
        return self.spec.unit

    @property
    def quantity(self) -> str:
        return self.spec.quantity

    @property
    def gt(self) -> float | None:
        return self.spec.gt

    @property
    def ge(self) -> float | None:
        return self.spec.ge

    @property
    def lt(self) -> float | None:
        return self.spec.lt

    @property
    def le(self) -> float | None:
        return self.spec.le


R = TypeVar("R", bound="CheckedRecord")


class CheckedRecord:
    """Base of the checked records; a subclass is a ``@dataclass(frozen=True)`` whose
    fields come from :func:`checked_field`, and sets:

    * ``error_type``: the ``ValueError`` subclass its problems are raised as;
    * ``unknown_key``: the message for a name that is no field, formatted with ``name``
      and ``value``.
    """

    error_type: ClassVar[type[ValueError]] = ValueError
    unknown_key: ClassVar[str] = "unknown key {name!r} (value {value!r})"

    def __post_init__(self) -> None:
        problems = []
        for info in self.field_info().values():
            value = getattr(self, info.name)
            try:
                object.__setattr__(self, info.name, _checked_value(info, value))
            except _FieldError as problem:
                problems.append(str(problem))
        if not problems:
            try:
                self._check_record()
            except ValueError as exc:
                problems.append(str(exc))
        if problems:
            raise self.error_type("; ".join(problems))

    def _check_record(self) -> None:
        """Checks across fields, run once every field is valid: raise ``ValueError`` with
        a message that says it all (no field name is added)."""

    @classmethod
    def field_info(cls) -> Mapping[str, FieldInfo]:
        """Every field, in declaration order."""
        return _field_info(cls)

    @classmethod
    def from_mapping(cls: type[R], values: Mapping[str, Any]) -> R:
        """A record from ``values`` (field name -> value); every unknown name and bad value
        is named in the one error raised."""
        known = cls.field_info()
        unknown = [
            cls.unknown_key.format(name=name, value=value)
            for name, value in values.items()
            if name not in known
        ]
        try:
            record = cls(**{name: value for name, value in values.items() if name in known})
        except cls.error_type as exc:
            raise cls.error_type("; ".join([*unknown, str(exc)])) from None
        if unknown:
            raise cls.error_type("; ".join(unknown))
        return record

    def as_dict(self) -> dict[str, Any]:
        """Field name -> value, in declaration order."""
        return {name: getattr(self, name) for name in self.field_info()}

    def replace(self: R, **changes: Any) -> R:
        """A checked copy with some fields changed (``p.replace(W=306.0, z_g=0.0)``)."""
        return type(self).from_mapping({**self.as_dict(), **changes})


class _FieldError(Exception):
    """One field's problem, as the one-line message that names it."""


_FIELD_INFO: dict[type, Mapping[str, FieldInfo]] = {}  # per record class, made once


def _field_info(cls: type) -> Mapping[str, FieldInfo]:
    known = _FIELD_INFO.get(cls)
    if known is not None:
        return known
    hints = typing.get_type_hints(cls)
    infos = {}
    for f in dataclasses.fields(cls):
        spec = f.metadata.get(_SPEC)
        if spec is None:
            raise TypeError(f"{cls.__name__}.{f.name}: declare it with checked_field()")
        kind = hints[f.name]
        if kind not in _CONVERTERS:
            raise TypeError(f"{cls.__name__}.{f.name}: type {kind!r} is not float/int/bool/str")
        infos[f.name] = FieldInfo(f.name, kind, f.default, spec)
    _FIELD_INFO[cls] = infos
    return infos


def _checked_value(info: FieldInfo, value: Any) -> Any:
    """``value`` converted to the field's type and checked; raises :class:`_FieldError`."""
    if value is REQUIRED:
        raise _FieldError(f"{info.name} is missing")
    converted = _CONVERTERS[info.kind](value)
    if converted is None:
        raise _FieldError(f"{info.name} = {value!r}: expected {_EXPECTED[info.kind]}")
    spec = info.spec
    broken = _broken_bounds(spec, converted)
    if broken:
        raise _FieldError(f"{info.name} = {value!r}: expected a number {broken}")
    if spec.min_length is not None and len(converted) < spec.min_length:
        plural = "" if spec.min_length == 1 else "s"
        raise _FieldError(
            f"{info.name} = {value!r}: expected at least {spec.min_length} character{plural}"
        )
    if spec.check is not None:
        try:
            spec.check(converted)
        except ValueError as exc:
            message = str(exc) if spec.standalone else f"{info.name} = {value!r}: {exc}"
            raise _FieldError(message) from None
    return converted


def _broken_bounds(spec: FieldSpec, value: Any) -> str:
    """The bounds ``value`` breaks, in words ('' if none)."""
    broken = []
    if spec.gt is not None and not value > spec.gt:
        broken.append(f"greater than {spec.gt:g}")
    if spec.ge is not None and not value >= spec.ge:
        broken.append(f"greater than or equal to {spec.ge:g}")
    if spec.lt is not None and not value < spec.lt:
        broken.append(f"less than {spec.lt:g}")
    if spec.le is not None and not value <= spec.le:
        broken.append(f"less than or equal to {spec.le:g}")
    return " and ".join(broken)


def _to_float(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    result = float(value)
    return result if math.isfinite(result) else None


def _to_int(value: Any) -> int | None:
    if isinstance(value, bool):
        return None
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real) and float(value).is_integer():
        return int(float(value))
    return None


def _to_bool(value: Any) -> bool | None:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, numbers.Integral) and int(value) in (0, 1):
        return bool(value)
    return None


def _to_str(value: Any) -> str | None:
    return value if isinstance(value, str) else None


_CONVERTERS: dict[type, Callable[[Any], Any]] = {
    float: _to_float,
    int: _to_int,
    bool: _to_bool,
    str: _to_str,
}
_EXPECTED: dict[type, str] = {
    float: "a finite number",
    int: "a whole number",
    bool: "true or false",
    str: "a text",
}
