"""Execute the copy-paste examples of the documentation, in order, as a user would.

:data:`DOCUMENTS` are the README, CONTRIBUTING.md and every page of docs/, run in that
order in one working folder: a page may use files an earlier one wrote (docs/studies.md
the README's ``turn.toml``). Every fenced code block must be preceded by one marker line:

* ``<!-- run -->``: run it (```` ```bash ```` with bash, ```` ```python ```` with this
  interpreter) in one working folder shared by the document's blocks, in document order;
  ``<!-- run: expect REGEX -->`` also requires REGEX in its standard output;
* ``<!-- excerpt of PATH -->``: every line of the block (but ``...``) is a line of PATH,
  a file an earlier block wrote, in the same order;
* ``<!-- not run: REASON -->``: reported as a skip with REASON.

A block without a marker fails the test, so no example goes unchecked by accident. A
block that fails because a shared library it needs is not installed on this machine (the
loader's "cannot open shared object file") is reported as a skip naming the library, and
the blocks after it still run. The
working folder starts with the session's built FMUs in ``build/fmus`` (with their content
hashes, so ``auv-cosim build --out build/fmus`` finds them up to date), and ``PATH`` starts
with this interpreter's folder, so ``python`` and ``auv-cosim`` are the tested ones.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from process_group import run_in_group

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md"))]
MARKER = re.compile(
    r"^<!-- (run|run: expect (?P<expect>.+)|excerpt of (?P<path>\S+)|not run: (?P<reason>.+)) -->$"
)
FENCE = re.compile(r"^```(\w*)\s*$")
MISSING_LIBRARY = re.compile(r"(\S+\.so[.\d]*): cannot open shared object file")


@dataclass(frozen=True)
class Block:
    document: Path
    line: int  # 1-based line of the opening fence
    language: str
    code: str
    marker: str | None  # the marker comment line, None if missing

    @property
    def id(self) -> str:
        return f"{self.document.name}:{self.line}"


def blocks(document: Path) -> list[Block]:
    """The fenced code blocks of ``document`` with the marker line right above each."""
    lines = document.read_text(encoding="utf-8").splitlines()
    result, i = [], 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if match is None:
            i += 1
            continue
        end = next(j for j in range(i + 1, len(lines)) if lines[j].strip() == "```")
        above = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
        marker = above.strip() if MARKER.match(above.strip()) else None
        result.append(
            Block(document, i + 1, match.group(1), "\n".join(lines[i + 1 : end]) + "\n", marker)
        )
        i = end + 1
    return result


@pytest.fixture
def workdir(fmu_paths: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("examples")
    fmus = folder / "build" / "fmus"
    fmus.mkdir(parents=True)
    for path in fmu_paths.values():
        shutil.copyfile(path, fmus / path.name)
        shutil.copyfile(f"{path}.sha256", fmus / f"{path.name}.sha256")
    # the FMUs nobody here wrote, where the docs name them in a checkout
    reference = Path("tests", "data", "reference-fmus")
    shutil.copytree(Path(__file__).parent / "data" / "reference-fmus", folder / reference)
    return folder


def _environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env.pop("PYTHONPATH", None)  # as a user's shell would have it
    return env


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: p.name)
def test_every_code_block_is_marked(document: Path) -> None:
    unmarked = [b.id for b in blocks(document) if b.marker is None]
    assert not unmarked, f"code blocks without a run/excerpt/not-run marker: {unmarked}"


# The documents whose examples a document's examples use, as a reader has them: docs/studies.md
# sweeps the README's turn.toml. They run first, in the same folder (each document gets a
# folder of its own, so the tests do not depend on their order or on sharing a process).
BUILDS_ON = {"studies.md": ("README.md",)}


@pytest.mark.slow
@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: p.name)
def test_examples_run_in_order(document: Path, workdir: Path) -> None:
    """All of a document's examples, one after another (later ones use earlier files),
    after those of the documents it builds on (``BUILDS_ON``)."""
    for name in BUILDS_ON.get(document.name, ()):
        (before,) = (d for d in DOCUMENTS if d.name == name)
        _run_examples(before, workdir)
    ran, missing = _run_examples(document, workdir)
    if ran == 0 and not missing:
        pytest.skip(f"{document.name} has no runnable example")
    if missing:
        pytest.skip(f"{ran} examples ran; skipped: " + "; ".join(missing))


def _run_examples(document: Path, workdir: Path) -> tuple[int, list[str]]:
    """Run ``document``'s examples in ``workdir``, in order; how many ran and, for those
    that need a library not installed here, why they did not."""
    ran, missing = 0, []
    for block in blocks(document):
        match = MARKER.match(block.marker or "")
        if match is None or match.group("reason"):
            continue
        if match.group("path"):
            _check_excerpt(block, workdir / match.group("path"))
            continue
        if block.language == "python":  # a script, as a user runs one (not python -c)
            script = workdir / f".example_{ran + 1}.py"
            script.write_text(block.code, encoding="utf-8")
            command = [sys.executable, str(script)]
        elif block.language in ("bash", "sh", "shell"):
            command = ["bash", "-euo", "pipefail", "-c", block.code]
        else:
            pytest.fail(f"{block.id}: cannot run a {block.language!r} block")
        # in a process group of its own, ended as it returns or times out: what an
        # example starts (a study's Dask workers, a viewer) does not outlive it
        done = run_in_group(command, timeout=600, cwd=workdir, env=_environment())
        library = MISSING_LIBRARY.search(done.stderr) if done.returncode != 0 else None
        if library is not None:
            missing.append(f"{block.id} needs {library.group(1)}, not installed here")
            continue
        assert done.returncode == 0, (
            f"{block.id} failed (exit {done.returncode}):\n{block.code}\n"
            f"--- stdout\n{done.stdout[-3000:]}\n--- stderr\n{done.stderr[-3000:]}"
        )
        if match.group("expect"):
            assert re.search(match.group("expect"), done.stdout), (
                f"{block.id}: output does not match {match.group('expect')!r}:\n{done.stdout}"
            )
        ran += 1
    return ran, missing


def _check_excerpt(block: Block, path: Path) -> None:
    assert path.is_file(), f"{block.id}: {path.name} was not written by the examples before it"
    actual = [line.strip() for line in path.read_text(encoding="utf-8").splitlines()]
    position = 0
    for line in block.code.splitlines():
        if not line.strip() or line.strip() == "...":
            continue
        try:
            position = actual.index(line.strip(), position) + 1
        except ValueError:
            pytest.fail(
                f"{block.id}: excerpt line {line.strip()!r} is not in {path.name} (in order)"
            )


def test_not_run_examples_say_why() -> None:
    """Examples we cannot execute here are listed with their reason (reported, not hidden)."""
    reasons = [
        (b.id, MARKER.match(b.marker).group("reason"))
        for d in DOCUMENTS
        for b in blocks(d)
        if b.marker and MARKER.match(b.marker).group("reason")
    ]
    for block_id, reason in reasons:
        assert len(reason) > 20, f"{block_id}: give a real reason, not {reason!r}"
    if reasons:
        pytest.skip("not executed here: " + "; ".join(f"{i} ({r})" for i, r in reasons))
