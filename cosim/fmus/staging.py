"""The FMU's Python code under one package named after its content: ``auvfmu_<hash>``.

pythonfmu ships an FMU's packages as top-level packages of ``resources/``, so a process
that loads two builds of one FMU (or two FMUs made with different pythonfmu versions)
imports the first one's modules for both. The build therefore puts every shipped package
(``plant_fmu``, ``controller_fmu``, ``fmu_runtime`` and pythonfmu's pure-Python package,
copied from the build environment) under one package whose name is taken from their
content (:func:`package_name`), and renames their absolute imports to it
(:func:`rename_imports`): the same sources give the same name (two extractions of one
build share the code), other sources another name (two builds never share a module).

Written by hand because no library renames imports while keeping every line where it
was (tracebacks and numba's line-keyed caches point at the same lines as the sources);
it works on tokens, so strings and comments are never touched, except a string passed
directly to ``import_module``, ``__import__`` or ``find_spec`` (an import by string).
"""

from __future__ import annotations

import hashlib
import io
import re
import tokenize
from collections.abc import Mapping

from cosim.errors import CosimError

PREFIX = "auvfmu_"
HASH_DIGITS = 12
_FORMAT = "rename-imports 1"  # part of the hash: a change to the renaming renames the package
_IMPORTS_BY_STRING = {"import_module", "__import__", "find_spec"}
_STATEMENT_START = {tokenize.NEWLINE, tokenize.NL, tokenize.INDENT, tokenize.DEDENT}


def package_name(files: Mapping[str, bytes]) -> str:
    """``auvfmu_<12 hex digits>``: the SHA-256 of the staged files (their paths and bytes)
    and of the renaming's format."""
    digest = hashlib.sha256(f"{_FORMAT}\n".encode())
    for path in sorted(files):
        digest.update(f"{path}\n{len(files[path])}\n".encode())
        digest.update(files[path])
    return PREFIX + digest.hexdigest()[:HASH_DIGITS]


def rename_imports(source: str, package: str, names: frozenset[str], where: str) -> str:
    """``source`` with every absolute import of the top-level packages ``names`` renamed
    into ``package`` (``from plant_fmu.x import y`` -> ``from auvfmu_....plant_fmu.x import
    y``; ``import plant_fmu`` -> ``import auvfmu_....plant_fmu as plant_fmu``), every line
    where it was.

    Raises:
        CosimError: ``import plant_fmu.x`` without ``as`` (it binds ``plant_fmu``, which
            a renamed import cannot), or a file that does not tokenize; ``where`` names it.
    """
    edits: list[tuple[int, int, str]] = []  # (row, column, text to insert there)
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    except (tokenize.TokenError, SyntaxError) as exc:
        raise CosimError(f"{where}: cannot be read as Python ({exc})") from None
    for i, token in enumerate(tokens):
        statement_start = (
            i == 0 or tokens[i - 1].type in _STATEMENT_START or (tokens[i - 1].string == ";")
        )
        if token.type == tokenize.NAME and statement_start and token.string == "from":
            first = tokens[i + 1]
            if first.type == tokenize.NAME and first.string in names:
                edits.append((*first.start, f"{package}."))
        elif token.type == tokenize.NAME and statement_start and token.string == "import":
            edits += _plain_imports(tokens, i + 1, package, names, where)
        elif token.type == tokenize.STRING and _imported_by_string(tokens, i):
            edits += _string_import(token, package, names)
    return _apply(source, edits)


def _plain_imports(
    tokens: list[tokenize.TokenInfo], i: int, package: str, names: frozenset[str], where: str
) -> list[tuple[int, int, str]]:
    """Edits for ``import a.b as c, d, ...`` whose names start at ``tokens[i]``."""
    edits = []
    while i < len(tokens) and tokens[i].type == tokenize.NAME:
        start, dotted = tokens[i], [tokens[i].string]
        i += 1
        while tokens[i].string == "." and tokens[i + 1].type == tokenize.NAME:
            dotted.append(tokens[i + 1].string)
            i += 2
        renamed = tokens[i].string == "as"
        if renamed:
            i += 2
        if dotted[0] in names:
            if len(dotted) > 1 and not renamed:
                raise CosimError(
                    f"{where}:{start.start[0]}: `import {'.'.join(dotted)}` cannot be renamed "
                    "into the FMU's package: write `from ... import ...` or `import ... as ...`"
                )
            edits.append((*start.start, f"{package}."))
            if not renamed:
                edits.append((*tokens[i - 1].end, f" as {dotted[0]}"))
        if tokens[i].string != ",":
            break
        i += 1
    return edits


def _imported_by_string(tokens: list[tokenize.TokenInfo], i: int) -> bool:
    """Whether ``tokens[i]`` is the first argument of an import function."""
    return (
        i >= 2
        and tokens[i - 1].string == "("
        and tokens[i - 2].type == tokenize.NAME
        and tokens[i - 2].string in _IMPORTS_BY_STRING
    )


def _string_import(
    token: tokenize.TokenInfo, package: str, names: frozenset[str]
) -> list[tuple[int, int, str]]:
    match = re.match(r"^([rRbBuU]*)(['\"])([A-Za-z_][\w.]*)\2$", token.string)
    if match is None or match.group(3).split(".")[0] not in names:
        return []
    row, column = token.start
    return [(row, column + len(match.group(1)) + 1, f"{package}.")]


def _apply(source: str, edits: list[tuple[int, int, str]]) -> str:
    lines = source.splitlines(keepends=True)
    for row, column, text in sorted(edits, reverse=True):
        line = lines[row - 1]
        lines[row - 1] = line[:column] + text + line[column:]
    return "".join(lines)
