"""Imported first by the workers' fork server (:mod:`cosim.study.fork_server`), before
numpy and Dask: sets Dask's pre-spawn environment (``distributed.nanny.pre-spawn-environ``:
one BLAS / OpenMP thread, malloc's trim threshold) in the server's process, so that every
worker forked from it has it, as Dask sets it before it spawns a worker. Never raises
(an exception other than ImportError would end the server; without the environment the
workers' BLAS starts a thread per core).

It also turns the garbage collector off for the server's imports: they make ~10^6 objects
and hardly any garbage, and the collections they set off walked all of them again (3 full
collections, ~0.12 s of the server's ~0.9 s, before the first worker could be forked).
:mod:`cosim.study.preload` turns it on again once what was imported is frozen."""

import gc
import os
from contextlib import suppress

from cosim.study.fork_server import pre_spawn_environ

gc.disable()

with suppress(Exception):
    os.environ.update(pre_spawn_environ())
