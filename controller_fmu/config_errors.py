"""One message for a controller configuration pydantic refused (both FMUs' configs)."""

from __future__ import annotations

from collections.abc import Collection

from pydantic import ValidationError


def validation_message(exc: ValidationError, what: str, standalone: Collection[str] = ()) -> str:
    """Every problem of ``exc`` in one line, ``; ``-separated: an unknown key as
    "unknown <what> parameter 'name'", a field in ``standalone`` (whose validator's message
    names the field and the bad entry itself) as that message, else
    "name = value: pydantic's reason"."""
    problems = []
    for err in exc.errors():
        name = ".".join(str(part) for part in err["loc"]) or "(config)"
        if err["type"] == "extra_forbidden":
            problems.append(f"unknown {what} parameter {name!r}")
        elif name in standalone and err["type"] == "value_error":
            problems.append(str(err["ctx"]["error"]))
        else:
            problems.append(f"{name} = {err.get('input')!r}: {err['msg']}")
    return "; ".join(problems)
