"""Files written whole or not at all: a temporary file beside the target, then a rename.

A kill leaves the old file (or none); a failed write (a full disk) leaves no half file
behind. The temporary file is ``.<name>.<pid>.tmp``, hidden and per process, which a run
folder's overwrite recognises as its own (:mod:`cosim.outputs.run_files`). Its name can be
predicted (a run folder's lock file holds the pid), so whatever has that name already (a
link planted in a folder from elsewhere) is removed and the file made anew, exclusively,
before it is written: nothing is written through a link. (In a folder others can write
while the file is written, a link swapped in between remains possible: keep outputs in
folders of your own.)
"""

import contextlib
import os
from collections.abc import Callable
from pathlib import Path


def write_whole(path: Path, write: Callable[[Path], object]) -> None:
    """Make ``path`` with ``write``, which writes the file it is given; raises OSError
    naming ``path`` (not the temporary file) when that fails."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        fresh_file(tmp)
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):  # a name too long fails its removal too
            tmp.unlink(missing_ok=True)
        why = os.strerror(exc.errno) if exc.errno else str(exc)
        raise OSError(exc.errno, why, str(path)) from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def fresh_file(tmp: Path) -> None:
    """Make ``tmp`` a new, empty regular file of this process, removing first what has the
    name (a stale file of a dead process of the same pid, a planted link: the link goes,
    never the file it names). Raises OSError (FileExistsError if a link comes back)."""
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
