"""Imported first by the workers' fork server (:mod:`cosim.study.fork_server`), before
numpy and Dask: sets Dask's pre-spawn environment (``distributed.nanny.pre-spawn-environ``:
one BLAS / OpenMP thread, malloc's trim threshold) in the server's process, so that every
worker forked from it has it, as Dask sets it before it spawns a worker. Never raises
(an exception other than ImportError would end the server; without the environment the
workers' BLAS starts a thread per core). Then it imports distributed, whose defaults file
is parsed by libyaml as the environment's was
(:func:`cosim.study.fork_server.libyaml_parsing`).

It also turns the garbage collector off for the server's imports: they make ~10^6 objects
and hardly any garbage, and the collections they set off walked all of them again (3 full
collections, ~0.12 s of the server's ~0.9 s, before the first worker could be forked).
:mod:`cosim.study.preload` turns it on again once what was imported is frozen.

And the server ignores SIGTERM and SIGHUP, as multiprocessing's fork server ignores SIGINT
itself: a stop signal sent to the whole process group (a CI job cancelled, ``kill --
-PGID``, a hangup) is the study's to handle, which closes its cluster, and the server ends
when the study does. Ended by the signal, the server no longer reported its workers' exits
to their nannies: each worker still running a run was killed after Dask's timeout, and left
its run's temporary folder behind. The workers forked from it ignore them too
(:mod:`cosim.study.preload`).

SIGINT is ignored too while the server imports (:mod:`cosim.study.server_exit`, imported
last, gives it back its default handler, which multiprocessing then sets aside for the
workers it forks as it starts ignoring SIGINT itself): a Ctrl-C while a sweep started
reached the server still importing, which printed a KeyboardInterrupt traceback of dozens
of lines under the command's one-line "interrupted". Before this module, while the
server's interpreter starts, the three are blocked (the command starts it so,
:func:`cosim.study.fork_server.start`): one that arrived meanwhile is dropped as they are
ignored here, and they are unblocked."""

import gc
import os
import signal
from contextlib import suppress

from cosim.study.fork_server import STOP_SIGNALS, libyaml_parsing, pre_spawn_environ

gc.disable()

for _signum in STOP_SIGNALS:
    signal.signal(_signum, signal.SIG_IGN)  # one that arrived while blocked is dropped
signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)

with suppress(Exception):
    os.environ.update(pre_spawn_environ())
# pyarrow (which pandas imports) starts jemalloc's background thread as it loads, and the
# server is to fork from one thread: a forked worker holds another thread's locks as they
# were (CPython 3.12 and later warn of it at each fork). Arrow's pool is mimalloc, not
# jemalloc, so the thread had nothing to purge.
os.environ.setdefault("JE_ARROW_MALLOC_CONF", "background_thread:false")

with libyaml_parsing():  # its defaults file, as the pre-spawn environment was read
    import distributed  # noqa: F401  (what every worker runs in)
