"""The dissertation's reference values: the data file and its loader."""

from __future__ import annotations

import numpy as np
import pytest
from reference_values import DISSERTATION

from cosim.analysis.reference_values import ReferenceValueError, load_reference_values


def test_every_entry_says_where_it_is_printed_and_in_what_unit():
    assert len(DISSERTATION) > 30
    for key, ref in DISSERTATION.items():
        assert ref.source.strip() and ref.description.strip(), key
        assert ref.unit, key
        if not isinstance(ref.unit, str):  # one unit per entry of a vector
            assert len(ref.unit) == len(ref.value), key


def test_values_keep_their_printed_digits():
    jacobian = DISSERTATION["example_5_3.jacobian_bar"]
    assert jacobian.text[2][0] == "-1.4050"  # a TOML float would print -1.405
    assert jacobian.resolution[2, 0] == pytest.approx(1e-4)
    assert jacobian.value[2, 0] == -1.405
    gains = DISSERTATION["table_6_2.gains"]
    assert gains.text == ["-0.7720", "10.345", "0.2100"]
    np.testing.assert_allclose(gains.resolution, [1e-4, 1e-3, 1e-4])
    count = DISSERTATION["example_5_1.equilibrium_count"]
    assert (count.text, count.value, count.resolution) == ("3", 3.0, 1.0)


def test_an_entry_may_give_its_tolerance_and_why():
    about = DISSERTATION["scenarios.cur_2_settling_time"]
    assert dict(about.tolerance) == {"absolute": 5.0} and "gridline" in about.tolerance_reason
    within = DISSERTATION["scenarios.bs_3_settling_time"]
    assert dict(within.tolerance) == {"at_most": True}
    plain = DISSERTATION["example_5_1.turn_positive_v"]
    assert (dict(plain.tolerance), plain.tolerance_reason) == ({}, "")


def test_mirrored_equilibria_are_printed_as_mirror_images():
    for group in ("example_5_1", "example_5_3", "low_speed"):
        plus = DISSERTATION[f"{group}.turn_positive_v"].value
        minus = DISSERTATION[f"{group}.turn_negative_v"].value
        np.testing.assert_array_equal(minus, plus * [1, *[-1] * (len(plus) - 1)])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[a.b]\nvalue = 1\nunit = "m"\nsource = "x"\n', r"'a\.b'.*description"),
        ('[a.b]\nvalue = "1.0"\nunit = "m"\nsource = "x"\ndescription = "y"\n', r"'1\.0' is not"),
        ('[a.b]\nvalue = [[1, 2], [3]]\nunit = "m"\nsource = "x"\ndescription = "y"\n', "rectang"),
        ("[a]\nb = 3\n", r"'a\.b': expected a table"),
        # loaded, it failed the page's first use as "ValueError: printed value NaN: ..."
        (
            '[a.b]\nvalue = nan\nunit = "m"\nsource = "x"\ndescription = "y"\n',
            r"values\.toml': entry 'a\.b': NaN is not a finite number",
        ),
        ("[a\n", "reference values"),
        (
            '[a.b]\nvalue = 1\nunit = "m"\nsource = "x"\ndescription = "y"\n'
            "tolerance = {absolute = 1, relative = 0.1}\n",
            r"'a\.b'.*tolerance.*expected one of",
        ),
        (
            '[a.b]\nvalue = 1\nunit = "m"\nsource = "x"\ndescription = "y"\n'
            "tolerance = {about = 1}\n",
            r"'a\.b'.*tolerance.*expected one of",
        ),
    ],
)
def test_a_malformed_file_is_refused_naming_the_entry(tmp_path, text, message):
    path = tmp_path / "values.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ReferenceValueError, match=message):
        load_reference_values(path)
