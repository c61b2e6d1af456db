"""``with_alias(fmu, dest, variable, alias)``: ``fmu`` copied to ``dest`` with ``alias``, a
second name of its ``variable`` (one value reference: an alias, as Modelica tools export
them), declared in its model description; the binary knows variables by value reference
only, so both names reach the same value."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr


def with_alias(fmu: Path, dest: Path, variable: str, alias: str) -> Path:
    """``fmu`` at ``dest`` with ``alias`` declared as ``variable`` is (its causality,
    variability and type, its value reference)."""
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(dest, "w") as out:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = _aliased(data.decode(), variable, alias).encode()
            out.writestr(item, data)
    return dest


def _aliased(text: str, variable: str, alias: str) -> str:
    declared = re.search(
        rf"<ScalarVariable\s+name={quoteattr(variable)}.*?</ScalarVariable>", text, re.DOTALL
    )
    if declared is None:
        raise ValueError(f"no variable {variable!r} in the model description")
    copy = declared[0].replace(f"name={quoteattr(variable)}", f"name={quoteattr(alias)}", 1)
    return text.replace("</ModelVariables>", copy + "</ModelVariables>", 1)
