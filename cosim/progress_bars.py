"""Progress bars on stderr (tqdm) that leave the process as they found it.

A run's or a study's bar may be drawn in a caller's long-lived process (a notebook kernel,
``cosim.run(..., progress=True)``), where tqdm, used as it comes, left two things behind
for good:

* its monitor thread, started with the first bar and no longer ended with the last one
  (tqdm 4.70): the bars here are made with no monitor (it only lowers a stalled bar's
  ``miniters``, and these bars refresh on every update anyway);
* multiprocessing's default start method, fixed as a side effect of tqdm's lock (a
  ``multiprocessing.RLock``, made with the first bar or :func:`write`): the caller's own
  ``multiprocessing.set_start_method`` then raised "context has already been set". The
  lock is made here with the start method left unchosen if it was.

tqdm is imported on first use, not with this module (it costs import time for no bar).
"""

from __future__ import annotations

import multiprocessing
import sys
from functools import cache
from typing import IO, Any


def progress_bar(**options: Any) -> Any:
    """A tqdm bar with ``options`` (tqdm's keywords), without tqdm's monitor thread;
    drawn nowhere where Python has no stderr (``sys.stderr`` None: ``pythonw``, a
    service), which tqdm would write to and fail."""
    if sys.stderr is None and options.get("file") is None:
        options = {**options, "disable": True}
    return _bar_class()(**options)


def write(line: str, file: IO[str]) -> None:
    """``line`` on ``file`` above the bars drawn there (tqdm clears them, writes and draws
    them again)."""
    _bar_class().write(line, file=file)


@cache
def _bar_class() -> Any:
    """tqdm's bar class without a monitor thread, its lock made (once: tqdm keeps it)."""
    from tqdm import tqdm

    class Bar(tqdm):
        monitor_interval = 0  # tqdm starts no monitor thread for this class

    before = multiprocessing.get_start_method(allow_none=True)
    try:
        Bar.get_lock()
    finally:
        if before is None:  # the lock's multiprocessing.RLock chose the default method
            multiprocessing.set_start_method(None, force=True)
    return Bar
