"""A command run with a folder it cannot write, also where the tests run as root, whom file
modes do not stop: :func:`read_only_prefix` gives the words to put before the command.

* A user other than root: the folder's write permissions are taken away (and given back
  by :func:`writable_again`, so pytest can remove it).
* Root: a read-only bind mount of the folder onto itself in a mount namespace of the
  command's own (``unshare -m``), which refuses root's writes too (``EROFS``); where the
  system allows no such namespace (a container without ``CAP_SYS_ADMIN``), the test is
  skipped, saying why.
"""

from __future__ import annotations

import os
import shutil
import stat
from pathlib import Path

import pytest
from process_group import run_in_group

_MOUNT = 'mount --bind -o ro "$0" "$0" && exec "$@"'


def read_only_prefix(folder: Path) -> list[str]:
    """The words that run a command with ``folder`` unwritable to it; skips the test where
    that cannot be arranged."""
    if os.geteuid() != 0:
        for path in [folder, *folder.rglob("*")]:
            mode = path.lstat().st_mode
            if not stat.S_ISLNK(mode):
                path.chmod(stat.S_IMODE(mode) & ~0o222)
        return []
    unshare = shutil.which("unshare")
    if unshare is None:
        pytest.skip("root ignores file modes, and unshare (a read-only bind mount) is missing")
    prefix = [unshare, "-m", "sh", "-c", _MOUNT, str(folder)]
    probe = run_in_group([*prefix, "sh", "-c", '! touch "$0/probe"', str(folder)], timeout=30)
    if probe.returncode != 0 or (folder / "probe").exists():
        pytest.skip(f"root ignores file modes, and no read-only bind mount here: {probe.stderr}")
    return prefix


def writable_again(folder: Path) -> None:
    """Give the owner back the write permission :func:`read_only_prefix` took away."""
    for path in [folder, *folder.rglob("*")]:
        if not path.is_symlink():
            path.chmod(path.stat().st_mode | stat.S_IWUSR)
