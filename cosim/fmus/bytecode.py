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
temporary folder.
"""

from __future__ import annotations

import py_compile
import tempfile
from collections.abc import Mapping
from pathlib import Path


def compiled(resources: Mapping[str, bytes]) -> dict[str, bytes]:
    """``resources`` path -> bytes of the checked-hash ``.pyc`` of every ``.py`` among
    ``resources`` (paths relative to ``resources/``, ``/``-separated), compiled by this
    Python; the paths are the ``__pycache__`` files this Python's import looks for. Raises
    :class:`py_compile.PyCompileError` naming a module that does not compile."""
    with tempfile.TemporaryDirectory(prefix="auv-cosim-bytecode-") as tmp:
        root = Path(tmp)
        for name, data in resources.items():
            if not name.endswith(".py"):
                continue
            source = root / name
            source.parent.mkdir(parents=True, exist_ok=True)
            source.write_bytes(data)
            # dfile: the file name the code objects record (importlib puts the real path
            # in when it loads them), the same whatever the build folder
            py_compile.compile(
                str(source),
                dfile=f"resources/{name}",
                doraise=True,
                invalidation_mode=py_compile.PycInvalidationMode.CHECKED_HASH,
            )
        return {
            path.relative_to(root).as_posix(): path.read_bytes()
            for path in sorted(root.rglob("*.pyc"))
        }
