"""The options a Python caller gives a run (``cosim.run``, ``Scenario.with_overrides``),
checked by type before they reach the scenario's checks: one line naming the keyword and
what was expected, the same for both (docs/api.md, Errors).

pydantic's own coercion would take a Decimal, a Fraction or a 0-d array as a float, refuse
``True`` in its own words and print an int of 400 digits whole, so the types are checked
here first; the ranges (finite, > 0) stay the scenario's and the runner's checks.
"""

from __future__ import annotations

from cosim.errors import CosimError, plain, shown


def seconds_argument(
    name: str, value: object, error: type[CosimError] = CosimError
) -> float | None:
    """A time in s: None, a float or int, or a numpy number of one, as a float; another
    type (a bool, a string such as ``"10 s"``, a Decimal, an array) or an int beyond the
    floats raises ``error`` naming ``name``."""
    value = plain(value)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise error(f"{name}={shown(value)}: expected a number of seconds (float or int)")
    try:
        return float(value)
    except OverflowError:
        raise error(f"{name}={shown(value)}: expected a finite number of seconds > 0") from None


def number_argument(name: str, value: object, error: type[CosimError] = CosimError) -> float | None:
    """None or a float or int within the floats (the caller checks its range), or a numpy
    number of one, as a float; else ``error`` naming ``name``."""
    value = plain(value)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or abs(value) > 1e300:
        raise error(f"{name}={shown(value)}: expected a finite number (float or int)")
    return float(value)


def choice_argument(
    name: str, value: object, choices: tuple[str, ...], error: type[CosimError] = CosimError
) -> str | None:
    """None or one of ``choices`` (a str: bytes or a list holding one are refused), else
    ``error`` naming ``name`` and the choices."""
    if value is None or (isinstance(value, str) and value in choices):
        return value
    raise error(f"{name}={shown(value)}: expected one of {', '.join(map(repr, choices))}")
