"""Files written whole or not at all: a temporary file beside the target, then a rename.

A kill leaves the old file (or none); a failed write (a full disk) leaves no half file
behind. The temporary file is ``.<name>.<pid>.tmp``, hidden and per process, which a run
folder's overwrite recognises as its own (:mod:`cosim.outputs.run_files`).
"""

import os
from collections.abc import Callable
from pathlib import Path


def write_whole(path: Path, write: Callable[[Path], object]) -> None:
    """Make ``path`` with ``write``, which writes the file it is given; raises OSError
    naming ``path`` (not the temporary file) when that fails."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        why = os.strerror(exc.errno) if exc.errno else str(exc)
        raise OSError(exc.errno, why, str(path)) from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
