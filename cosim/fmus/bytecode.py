"""The compiled form of an FMU's Python code, shipped beside it in ``resources/``.

A process that imports Python code from a folder without compiled files compiles it first:
about 0.1 s for each of our FMUs (54 modules), paid by every host at every fresh
extraction of the FMU (fmpy extracts into a new temporary folder each time) and, before
this, by a local study's client for all its workers. The FMU therefore carries, for the
Python it was built with, each module's ``__pycache__/<module>.<tag>.pyc`` in the
*checked-hash* form of PEP 552: the file holds a hash of its source, which the importing
Python compares with the source's before using it, so an extraction's new file times do
not invalidate it (timestamp-based files would be) and an edited source is never run
stale. Another Python (another cache tag) ignores them and compiles as before.

Written with the standard library's :func:`py_compile.compile` (what ``python -m compileall
--invalidation-mode checked-hash`` does for each file), on the resources staged in a
temporary folder, in a fresh isolated Python (``-I``: nothing of the caller's environment
imported): marshal marks a string it meets twice by reference, and a string the process
holds elsewhere too (one it interned, as importing a module that names it does) is
written another way, so the same sources compiled in the building process gave other
bytes after it had imported other code (a notebook building after a run; a test session).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from collections.abc import Mapping
from pathlib import Path

from cosim.errors import CosimError

# What the fresh Python runs: every .py under the folder (argv[1]), in name order
_COMPILE = """
import pathlib, py_compile, sys
root = pathlib.Path(sys.argv[1])
for source in sorted(root.rglob("*.py")):
    name = source.relative_to(root).as_posix()
    try:
        py_compile.compile(
            str(source), dfile="resources/" + name, doraise=True,
            invalidation_mode=py_compile.PycInvalidationMode.CHECKED_HASH,
        )
    except py_compile.PyCompileError as error:
        sys.exit(f"{error.exc_type_name}: {error.exc_value}")
"""


def compiled(resources: Mapping[str, bytes]) -> dict[str, bytes]:
    """``resources`` path -> bytes of the checked-hash ``.pyc`` of every ``.py`` among
    ``resources`` (paths relative to ``resources/``, ``/``-separated), compiled by this
    Python in a process of its own; the paths are the ``__pycache__`` files this Python's
    import looks for.

    Raises:
        CosimError: a module does not compile (the compiler's last line, naming it).
    """
    with tempfile.TemporaryDirectory(prefix="auv-cosim-bytecode-") as tmp:
        root = Path(tmp)
        for name, data in resources.items():
            if not name.endswith(".py"):
                continue
            source = root / name
            source.parent.mkdir(parents=True, exist_ok=True)
            source.write_bytes(data)
        # dfile: the file name the code objects record (importlib puts the real path in
        # when it loads them), the same whatever the build folder
        done = subprocess.run(
            [sys.executable, "-I", "-c", _COMPILE, str(root)],
            capture_output=True,
            text=True,
            check=False,
        )
        if done.returncode != 0:
            lines = done.stderr.strip().splitlines() or [f"exit status {done.returncode}"]
            raise CosimError(f"cannot compile the FMU's Python code: {lines[-1]}")
        return {
            path.relative_to(root).as_posix(): path.read_bytes()
            for path in sorted(root.rglob("*.pyc"))
        }
