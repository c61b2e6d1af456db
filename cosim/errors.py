"""The one exception type the command line turns into a one-line reason."""


class CosimError(Exception):
    """A user-facing failure: bad scenario, failed FMU call, unwritable output, ..."""
