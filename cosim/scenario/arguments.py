"""The options a Python caller gives a run (``cosim.run``, ``Scenario.with_overrides``),
checked by type before they reach the scenario's checks: one line naming the keyword and
what was expected, the same for both (docs/api.md, Errors).

pydantic's own coercion would take a Decimal, a Fraction or a 0-d array as a float, refuse
``True`` in its own words and print an int of 400 digits whole, so the types are checked
here first; the ranges (finite, > 0) stay the scenario's and the runner's checks.
"""

from __future__ import annotations

import os

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


def home_expanded(text: str) -> str:
    """``text`` with a leading ``~`` or ``~user`` made the home folder, as a shell does
    (``~/runs`` is the home folder's, as pandas reads it: Python's own calls would make a
    folder named ``~`` in the working folder, which a shell's ``rm -rf ~`` then removes);
    for the API's path arguments, the command's path options (``--out=~/x``, which the
    shell leaves) and a study file's scenario. ValueError, saying why and what to write
    instead, for a ``~user`` with no home folder (no such user, or no HOME)."""
    expanded = os.path.expanduser(text)
    if expanded.startswith("~"):  # no such user, or no HOME and no password entry
        user = text.replace(os.altsep or os.sep, os.sep).split(os.sep, 1)[0]  # "~name"
        raise ValueError(
            f"no home folder for {user!r} (no such user, or no HOME); expected ~/... with "
            f"HOME set, or ./{text} for a name starting with ~"
        )
    return expanded
