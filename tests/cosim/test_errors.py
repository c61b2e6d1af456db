"""How the command says a library's warning (cosim/errors.py)."""

from __future__ import annotations

import warnings

from numba_warnings import NUMBA_PARSE_WARNING

from cosim.errors import one_line_warnings


def test_a_warning_carrying_a_traceback_is_said_without_it(capsys):
    """``NUMBA_OPT=9 auv-cosim run bs-3`` printed numba's warning with the whole
    traceback it holds flattened into the line (file names, source lines, carets).
    Said: the warning's words and the exception, on one line."""
    show = one_line_warnings("auv-cosim run")
    show(UserWarning(NUMBA_PARSE_WARNING), UserWarning, "config.py", 185)
    assert capsys.readouterr().err == (
        "auv-cosim run: warning: Environment variable 'NUMBA_OPT' is defined but its "
        "associated value '9' could not be parsed. The parse failed with exception: "
        "ValueError: Environment variable `NUMBA_OPT` is set to an unsupported value '9', "
        "supported values are 0, 1, 2, 3, and 'max'\n"
    )


def test_a_plain_warning_is_one_line_as_before(capsys):
    show = one_line_warnings("auv-cosim run")
    with warnings.catch_warnings():
        show(RuntimeWarning("two\n  lines"), RuntimeWarning, "x.py", 1)
    assert capsys.readouterr().err == "auv-cosim run: warning: two lines\n"
