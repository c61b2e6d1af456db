"""Imported last by the workers' fork server (:mod:`cosim.study.fork_server`): the server
ends without its interpreter's teardown, and SIGINT, ignored while it imported
(:mod:`cosim.study.server_environ`), has its default handler back: multiprocessing's server
saves the handler it finds as it starts ignoring SIGINT, and gives it to each worker it
forks, which takes a Ctrl-C as Python does.

The server ends when its pipe from the command that started it closes: as ``auv-cosim
sweep`` has closed its cluster (:func:`cosim.study.fork_server.stop`), or as a process
that did not stop it ends (a test's, a killed command's).
An interpreter that imported numba, distributed and the engine then spends ~0.05 s
tearing its modules down, and the server holds the command's stderr until it has ended:
a pipe reading the command (``auv-cosim sweep ... | tee``, a test, a benchmark) waited
that long after the command itself (``python scripts/sweep_timeline.py``: "process exit"
to "pipes closed" 0.04-0.05 s, 0.00-0.01 s with this). The server holds nothing to flush
or to release: the workers it forked end on their own (each calls ``os._exit``, so they
never run this), its socket's folder is the command's to remove.

Registered last, :func:`os._exit` runs first among the server's exit handlers (they run in
the reverse order of their registration) and ends the process before the others.
"""

import atexit
import os
import signal

signal.signal(signal.SIGINT, signal.default_int_handler)
atexit.register(os._exit, 0)
