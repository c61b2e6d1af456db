"""Checked records: what a field accepts, what it refuses, and how the refusal reads."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from plant_fmu.model.validated import REQUIRED, CheckedRecord, checked_field


class RecordError(ValueError):
    pass


def _even(value: int) -> None:
    if value % 2:
        raise ValueError("expected an even number")


@dataclasses.dataclass(frozen=True)
class Record(CheckedRecord):
    error_type = RecordError
    unknown_key = "unknown record parameter {name!r}"

    mass: float = checked_field(description="a mass, kg", unit="kg", gt=0.0)
    ratio: float = checked_field(0.5, description="a ratio", ge=0.0, le=1.0)
    count: int = checked_field(2, description="a count", check=_even)
    on: bool = checked_field(False, description="a switch")
    label: str = checked_field("x", description="a label", min_length=1)

    def _check_record(self) -> None:
        if self.mass * self.ratio > 100.0:
            raise ValueError(f"mass * ratio = {self.mass * self.ratio:g}: expected <= 100")


def test_values_are_converted_to_the_field_types():
    record = Record(mass=3, ratio=np.float64(0.25), count=np.int64(4), on=np.bool_(True))
    assert record.as_dict() == {"mass": 3.0, "ratio": 0.25, "count": 4, "on": True, "label": "x"}
    assert [type(v) for v in record.as_dict().values()] == [float, float, int, bool, str]
    assert Record(mass=1.0, count=6.0).count == 6  # a whole float is a whole number
    assert Record(mass=1.0, on=1).on is True  # FMI Booleans arrive as 0/1


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({}, r"^mass is missing$"),
        ({"mass": 0.0}, r"^mass = 0\.0: expected a number greater than 0$"),
        ({"mass": -1}, r"^mass = -1: expected a number greater than 0$"),
        ({"mass": math.nan}, r"^mass = nan: expected a finite number$"),
        ({"mass": math.inf}, r"^mass = inf: expected a finite number$"),
        ({"mass": "1.0"}, r"^mass = '1\.0': expected a finite number$"),
        ({"mass": True}, r"^mass = True: expected a finite number$"),
        ({"mass": 1.0, "ratio": 1.5}, r"^ratio = 1\.5: expected a number less than or equal to 1$"),
        ({"mass": 1.0, "count": 2.5}, r"^count = 2\.5: expected a whole number$"),
        ({"mass": 1.0, "count": 3}, r"^count = 3: expected an even number$"),
        ({"mass": 1.0, "on": 2}, r"^on = 2: expected true or false$"),
        ({"mass": 1.0, "label": ""}, r"^label = '': expected at least 1 character$"),
        ({"mass": 1.0, "label": 5}, r"^label = 5: expected a text$"),
        ({"mass": 300.0}, r"^mass \* ratio = 150: expected <= 100$"),
        (
            {"mass": -1.0, "count": 3, "lable": "y"},
            r"^unknown record parameter 'lable'; mass = -1\.0: expected a number greater than "
            r"0; count = 3: expected an even number$",
        ),
    ],
)
def test_every_bad_value_is_named_with_what_is_expected(values, message):
    with pytest.raises(RecordError, match=message):
        Record.from_mapping(values)


def test_a_record_is_frozen_hashable_and_replaced_through_the_checks():
    record = Record(mass=2.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        record.mass = 3.0  # type: ignore[misc]
    assert hash(record) == hash(Record(mass=2.0)) and record == Record(mass=2.0)
    assert record.replace(ratio=1.0) == Record(mass=2.0, ratio=1.0)
    with pytest.raises(RecordError, match=r"^ratio = -1\.0: expected a number greater than"):
        record.replace(ratio=-1.0)
    with pytest.raises(RecordError, match=r"^unknown record parameter 'rate'$"):
        record.replace(rate=1.0)


def test_field_info_gives_type_default_range_and_unit_in_declaration_order():
    info = Record.field_info()
    assert list(info) == ["mass", "ratio", "count", "on", "label"]
    assert [f.kind for f in info.values()] == [float, float, int, bool, str]
    assert info["mass"].default is REQUIRED and info["ratio"].default == 0.5
    assert (info["mass"].gt, info["mass"].ge, info["mass"].unit) == (0.0, None, "kg")
    assert (info["ratio"].ge, info["ratio"].le, info["ratio"].description) == (0.0, 1.0, "a ratio")


def test_a_field_declared_without_checked_field_is_refused():
    @dataclasses.dataclass(frozen=True)
    class Loose(CheckedRecord):
        size: float = 1.0

    with pytest.raises(TypeError, match=r"Loose\.size: declare it with checked_field"):
        Loose()
