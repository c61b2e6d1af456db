"""A thin fmpy ``FMU2Slave`` driver for tests: set/get by name, capture the FMU's log.

Importable from test files (``from fmu_harness import Harness``) and from fresh
subprocesses (put this folder on ``sys.path`` first).
"""

from __future__ import annotations

import shutil
from collections.abc import Iterable
from ctypes import byref
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    free,
)
from fmpy.logging import addLoggerProxy

STATUS_OK, STATUS_DISCARD, STATUS_ERROR = 0, 2, 3


def status_of(call, *args, **kwargs) -> int:
    """The FMI status of an fmpy call: 0 if it returned, else the status fmpy raised
    (fmpy raises on Discard, Error and Fatal)."""
    try:
        call(*args, **kwargs)
    except FMICallException as exc:
        return exc.status
    return STATUS_OK


class Harness:
    """One FMU instance through fmpy, with its log messages in ``self.log``.

    ``Harness(path, instance="plant", **values)`` instantiates (logging on), enters
    initialisation mode, writes ``values`` by name and exits initialisation mode; with
    ``initialize=False`` it only instantiates. Without ``unzip_dir`` it extracts the FMU
    into a folder of its own, which ``close`` deletes.
    """

    def __init__(
        self,
        path: Path | str,
        instance: str = "plant",
        unzip_dir: str | None = None,
        initialize: bool = True,
        **values,
    ) -> None:
        md = read_model_description(str(path))
        self.variables = {v.name: v for v in md.modelVariables}
        self.log: list[tuple[int, str]] = []
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._on_log)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(self._callbacks))
        self._own_dir = None if unzip_dir else extract(str(path))
        self.slave = FMU2Slave(
            guid=md.guid,
            unzipDirectory=unzip_dir or self._own_dir,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=instance,
        )
        self.slave.instantiate(callbacks=self._callbacks, loggingOn=True)
        self.time = 0.0
        self.initialised = False  # fmi2Terminate is allowed only then (FMI 2.0)
        if initialize:
            self.initialize(**values)

    def initialize(self, **values) -> None:
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.set(**values)
        self.slave.exitInitializationMode()
        self.initialised = True
        self.time = 0.0

    def _on_log(self, component, instance, status, category, message) -> None:
        self.log.append((int(status), message.decode("utf-8")))

    def messages(self, min_status: int = 0) -> str:
        """The log messages with at least ``min_status`` (3 = error), one per line."""
        return "\n".join(text for status, text in self.log if status >= min_status)

    def try_initialize(self, **values) -> tuple[int, int]:
        """Initialise, writing ``values`` in initialisation mode, without raising: the
        worst status of the writes and the status of exitInitializationMode."""
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        writes = [status_of(self.set, **{name: value}) for name, value in values.items()]
        self.time = 0.0
        leave = status_of(self.slave.exitInitializationMode)
        self.initialised = leave == STATUS_OK
        return max(writes, default=STATUS_OK), leave

    def set(self, **values) -> None:
        for name, value in values.items():
            var = self.variables[name]
            setter = getattr(self.slave, f"set{var.type}")
            setter([var.valueReference], [value])

    def get(self, *names: str) -> np.ndarray:
        return np.array([self.slave.getReal([self.variables[n].valueReference])[0] for n in names])

    def get_all(self, names: Iterable[str]) -> np.ndarray:
        return np.array(self.slave.getReal([self.variables[n].valueReference for n in names]))

    def step(self, h: float, at: float | None = None) -> int:
        """One doStep of h seconds from ``self.time`` (or the communication point ``at``);
        the FMI status (0 OK, 2 Discard, ...). On success ``self.time`` is the step's end."""
        t = self.time if at is None else at
        try:
            self.slave.doStep(t, h)
        except FMICallException as exc:
            return exc.status
        self.time = t + h
        return STATUS_OK

    def run(self, duration: float, h: float, names: Iterable[str]) -> np.ndarray:
        """Step ``duration`` seconds and return ``names`` after each step (one row each)."""
        names = list(names)
        rows = []
        for _ in range(round(duration / h)):
            if self.step(h) != STATUS_OK:
                raise RuntimeError(f"doStep failed at t = {self.time}: {self.messages(3)}")
            rows.append(self.get_all(names))
        return np.array(rows)

    def close(self) -> None:
        """Terminate (when initialised) and free the instance, delete its extraction."""
        if self.initialised:
            self.slave.terminate()
        self.slave.freeInstance()
        if self._own_dir is not None:
            shutil.rmtree(self._own_dir, ignore_errors=True)
