"""A library warning carrying a whole traceback, as numba writes one, for the tests of how
the command and the FMUs say warnings in one line."""

# numba's warning of a NUMBA_* value it cannot parse (numba/core/config.py), as it reads
NUMBA_PARSE_WARNING = (
    "Environment variable 'NUMBA_OPT' is defined but its associated value '9' could not "
    "be parsed.\nThe parse failed with exception:\nTraceback (most recent call last):\n"
    '  File "numba/core/config.py", line 185, in _readenv\n    return ctor(value)\n'
    "           ^^^^^^^^^^^\nValueError: Environment variable `NUMBA_OPT` is set to an "
    "unsupported value '9', supported values are 0, 1, 2, 3, and 'max'\n"
)
