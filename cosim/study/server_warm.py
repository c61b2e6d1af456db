"""Imported by the workers' fork server (:mod:`cosim.study.fork_server`) after the run's
modules (:mod:`cosim.study.preload`), for ``auv-cosim sweep``'s own server only: the
study's warm-up (:func:`cosim.study.task.warm_up`), done once in the server before it forks
any worker, so that every worker starts with the FMUs' package imported, their compiled
kernels loaded from numba's cache and their libraries loaded.

Each worker paid that warm-up in its first task (~0.13-0.16 s of CPU for bs-3, ~0.02 s
left once the server has done it; ``docs/performance.md``): two workers paid it twice,
on the two cores the runs need. The server does not know the study as it starts (it
starts before the study is read, so that its imports run beside the client's): it waits
for the client to hand it over (:func:`cosim.study.fork_server.hand_over`: the study's
:class:`~cosim.study.execution.Job`, written whole into the file named by
:data:`~cosim.study.fork_server.WARM_VARIABLE`) while its workers' fork requests wait in
its socket, as long as the client checks the study (an FMU build, a large plan: it hands
the study over, or says that none is coming, on every path of the command), and gives up,
warming nothing, once the client has ended or has said so (each worker then warms up in
its first task, as without this), or, a guard against a client that never says, after
WAIT_S. Where the server has warmed up, its workers do not again
(:func:`cosim.study.fork_server.warmed`): a worker's warm-up after the server's was
another run of one step, ~0.015 s of CPU that no later run needs, and ~0.013 s that a
forked process pays once (pages copied on write among it), which its first run now
pays. Nothing of the warm-up is live as the server forks: the FMU instances are freed,
no thread is left, the run's scratch folder is removed. Never raises: a failed warm-up
leaves it to the workers, whose first run reports the reason.
"""

import gc
import os
import pickle
import time
from contextlib import suppress
from pathlib import Path

from cosim.study.fork_server import WARM_VARIABLE, mark_warmed

# s the server waits for the study at most while its client lives: the client checks it
# meanwhile, which took over 5 s (the wait until then: its workers started unwarmed), and
# says when none is coming; this only ends the wait of a client that never says
WAIT_S = 600.0
POLL_S = 0.005  # s between two looks for the hand-over file


def handed_over(path: Path, parent: int, wait_s: float = WAIT_S) -> bytes | None:
    """The hand-over file's bytes once it exists (the file then removed); None once the
    process ``parent`` (the client that started this one) has ended or ``wait_s``
    passed. Polled: the server has no channel from the client but the file (it is started
    with only its socket and its pipe to the client open). Giving up after ``wait_s``, it
    makes the file itself, empty, where the client's would have come: a study handed over
    later finds it there and is not taken (:func:`cosim.study.fork_server.hand_over`);
    one handed over just before is read."""
    deadline = time.monotonic() + wait_s
    while os.getppid() == parent:
        with suppress(FileNotFoundError):
            content = path.read_bytes()
            path.unlink(missing_ok=True)
            return content
        if time.monotonic() >= deadline and _given_up(path):
            return None
        time.sleep(POLL_S)
    return None


def _given_up(path: Path) -> bool:
    """Whether this process made ``path`` (empty), saying it waits no longer; not if the
    client's hand-over is there first (then to be read), nor if it cannot be made."""
    try:
        os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
    except FileExistsError:
        return False
    except OSError:
        pass  # the client cannot hand over into that folder either
    return True


def warm(content: bytes) -> None:
    """Warm up as a local worker of the study pickled in ``content`` would (its
    :meth:`~cosim.study.execution.StudyPlugin.warm`): the FMUs the client extracted, its
    copies of the FMU files, whose interfaces the client read (handed over with the study:
    not read again, :func:`cosim.fmus.interface.given_interface`); this process's scratch
    folder, which the run made, removed."""
    from cosim import scratch
    from cosim.fmus.interface import given_interface
    from cosim.study.task import warm_up
    from cosim.study.unpacked import use_unpacked

    job, interfaces = pickle.loads(content)
    paths = {instance: Path(path) for instance, path in job.fmu_files.items()}
    if not all(path.is_absolute() for path in paths.values()):
        return  # FMUs carried to the workers, not the client's copies: theirs to load
    for path, interface in interfaces.items():
        with suppress(OSError):  # gone: the run says so, as before
            given_interface(path, interface)
    use_unpacked(job.unpacked)
    try:
        warm_up(job.base, paths)
    finally:
        scratch.remove_own()
    mark_warmed(job.plugin)  # the workers forked from now on need not warm up again


def _warm_from_client() -> None:
    """Warm up on the study the client named in :data:`WARM_VARIABLE` hands over; its
    process id is named there too, not taken as this process's parent once the imports
    are done: a client that ended before (a sweep refused at once) has nothing to wait for."""
    client, _, named = os.environ.pop(WARM_VARIABLE, "").partition(":")
    if not client.isdigit() or not named:
        return
    content = handed_over(Path(named), int(client))
    if not content:  # none in time, or the client's study ended without one
        return
    with suppress(Exception):
        warm(content)
    # what the run left in reference cycles (its slaves, its run folder, the FMUs' models:
    # ~300 objects, ~4 ms) freed now, not frozen into every worker; what the warm-up
    # loaded, out of the forked workers' collections' reach
    gc.collect()
    gc.freeze()


_warm_from_client()
