"""Imported first by the workers' fork server (:mod:`cosim.study.fork_server`), before
numpy and Dask: sets Dask's pre-spawn environment (``distributed.nanny.pre-spawn-environ``:
one BLAS / OpenMP thread, malloc's trim threshold) in the server's process, so that every
worker forked from it has it, as Dask sets it before it spawns a worker. Never raises
(an exception other than ImportError would end the server; without the environment the
workers' BLAS starts a thread per core)."""

import os
from contextlib import suppress

from cosim.study.fork_server import pre_spawn_environ

with suppress(Exception):
    os.environ.update(pre_spawn_environ())
