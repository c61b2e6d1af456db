"""One FMU instance as the master drives it (fmpy ``FMU2Slave``), and its log.

:class:`Slave` holds the pre-resolved value references, the input buffer and output view
the stepping loop uses, the FMU's logged messages (warnings and worse) and its FMI state;
:func:`describe` turns a failed call into the one-line reason a run reports. FMU files are
extracted once per process (:func:`unzipped`), and each FMU's shared library is loaded
once per process and instance name: a finished run's fmpy ``FMU2Slave`` waits, instance
freed and library loaded, for the next run of this process (:func:`_library`).
"""

from __future__ import annotations

import collections
import contextlib
import ctypes
import hashlib
import os
import shutil
import sys
import tempfile
import threading
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import calloc, free
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2LastSuccessfulTime,
    fmi2Status,
    fmi2Terminated,
)

from cosim.engine.extrapolation import InputRates
from cosim.errors import CosimError, seconds
from cosim.fmus import native
from cosim.fmus.interface import FmuInterfaceError, extract_fmu, root_attributes
from cosim.limits import unwritten
from cosim.progress_bars import write
from cosim.scenario.spec import Instance
from cosim.scratch import process_folder
from fmu_runtime import exit_guard
from fmu_runtime.log_text import shortened

STATUS_LABELS = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
WARNING, DISCARD, PENDING = 1, 2, 5  # fmi2Status values
# the statuses a call passes with: any other stops the run, a number out of the enum too
# (fmpy's wrappers raise on a status above fmi2Warning only: -1 went as a warning)
PASSED = (0, WARNING)
LOG_LINES_KEPT = 20  # logged messages (warning or worse) kept per instance
_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


class Slave:
    """One FMU instance as the master drives it: the fmpy slave, pre-resolved value
    references, its input buffer and output view, its logged messages and FMI state.

    The FMI 2.0 call order is enforced by ``_expect``: new -> instantiated ->
    initialization -> stepping -> terminated -> freed. After an Error status the instance
    is only freed, after Fatal it is not touched again, as the standard requires.
    """

    def __init__(self, instance: Instance, unzip_dir: Path, k: int) -> None:
        md = instance.model_description
        self.name = instance.name
        self.instance = instance
        self.k = k
        # takes input derivatives (fmi2SetRealInputDerivatives, cosim.engine.extrapolation)
        self.interpolates = bool(md.coSimulation.canInterpolateInputs)
        # an output depends directly on a connected input: refreshed at every point
        self.feeds_through = False
        self.state = "new"
        self.messages: collections.deque[str] = collections.deque(maxlen=LOG_LINES_KEPT)
        self.logged = 0  # messages logged (warning or worse), those left out of messages too
        # fmi2SetDebugLogging's categories: None off, () every one (cosim.scenario.spec)
        self.debug_logging = instance.debug_logging
        self.verbatim_log = False  # its messages are text, not printf formats (load)
        _check_same_fmu(instance, unzip_dir)
        self._key = (str(unzip_dir), md.coSimulation.modelIdentifier, md.guid, instance.name)
        self.fmu = _library(self._key)
        # the instance's fmi2Component for the hot path's C calls (set once instantiated)
        self.handle = ctypes.c_void_p()

    def bind(
        self,
        inputs: list[tuple[Any, int]],
        outputs: list[Any],
        out: np.ndarray,
        input_rates: InputRates | None = None,
    ) -> None:
        """Resolve the buffers once: each input (an fmpy variable) comes from ``z[index]``,
        the outputs go to ``out`` (a view of z, the Real ones first). Integer, Enumeration
        and Boolean values travel as numbers in z (``others``), outside the Real fast
        path. ``input_rates`` sends the Real inputs' derivatives (extrapolation)."""
        real_inputs = [(v.valueReference, i) for v, i in inputs if v.type == "Real"]
        real_outputs = [v.valueReference for v in outputs if v.type == "Real"]
        self.n_inputs, self.n_outputs = len(real_inputs), len(real_outputs)
        self.input_vrs = (ctypes.c_uint * self.n_inputs)(*(vr for vr, _ in real_inputs))
        self.inputs = np.zeros(self.n_inputs)
        self.input_ptr = self.inputs.ctypes.data_as(_DOUBLE_P)
        self.input_sources = np.asarray([i for _, i in real_inputs], dtype=np.intp)
        self.output_vrs = (ctypes.c_uint * self.n_outputs)(*real_outputs)
        self.output_ptr = out.ctypes.data_as(_DOUBLE_P)
        self.other_inputs = [(v.type, [v.valueReference], i) for v, i in inputs if v.type != "Real"]
        self.other_outputs = [
            (v.type, [v.valueReference], out[j:]) for j, v in enumerate(outputs) if v.type != "Real"
        ]
        self.others = bool(self.other_inputs or self.other_outputs)
        self.input_rates = input_rates
        # (c, t, h, flag): the adaptive loop's
        self.do_step = _checked(self.fmu, "fmi2DoStep", self.note_warning)
        # the stepping loop's calls, every argument bound (:func:`_hot_calls`)
        self.put_inputs, self.read_reals, self.advance = _hot_calls(self)

    def set_others(self, z: np.ndarray) -> None:
        """Set the connected Integer, Enumeration and Boolean inputs from z."""
        for kind, vrs, i in self.other_inputs:
            if kind == "Boolean":
                self.fmu.setBoolean(vrs, [bool(z[i])])
            else:
                self.fmu.setInteger(vrs, [int(z[i])])

    def get_others(self) -> None:
        """Read the Integer, Enumeration and Boolean outputs into z (Booleans as 0, 1)."""
        for kind, vrs, view in self.other_outputs:
            get = self.fmu.getBoolean if kind == "Boolean" else self.fmu.getInteger
            view[0] = float(get(vrs)[0])

    def exchange(self, z: np.ndarray) -> None:
        """Set every connected input from z and read every output back (not the hot path:
        initialisation, rollback and the adaptive algorithm)."""
        z.take(self.input_sources, out=self.inputs)
        self.put_inputs()
        self.set_others(z)
        self.read_outputs()

    def _expect(self, *states: str) -> None:
        if self.state not in states:
            raise CosimError(f"{self.name}: FMI call out of order (in state {self.state!r})")

    def _logging_on(self) -> bool:
        """fmi2Instantiate's loggingOn: on where the instance's debug log is asked for, and
        for an FMU without our runtime (pythonfmu's own binary, instantiated with logging
        off, drops its warnings and errors too; its debug messages are dropped in
        :func:`_log`). Our runtime passes warnings and errors either way, so our FMUs do no
        debug work nobody reads (FMI 2.0, 2.1.5: every category is on with loggingOn)."""
        from fmpy import platform

        folder = Path(self.fmu.unzipDirectory)
        return self.debug_logging is not None or not native.loader_in_folder(folder, platform)

    def load(self, stop_time: float) -> None:
        """instantiate (logging on), the instance's debug logging if the scenario turns it
        on (fmi2SetDebugLogging with its categories, FMI 2.0, 2.1.5: before
        initialisation, so that the FMU's debug messages of its set-up are shown too),
        setupExperiment and the start values."""
        from fmpy.logging import addLoggerProxy

        self._expect("new")
        self.callbacks = fmi2CallbackFunctions()  # kept on self: the FMU holds pointers into it
        self.callbacks.logger = _LOGGER
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.callbacks.componentEnvironment = id(self)
        # fmpy's native proxy formats the FMU's printf-style messages; it keeps ONE target
        # function per process, so every instance shares _LOGGER, which dispatches on the
        # componentEnvironment the FMU passes back. An FMU whose messages are no formats
        # calls _LOGGER itself (its five arguments are those of every call it makes).
        self.verbatim_log = not _formats_messages(Path(self.fmu.unzipDirectory))
        if not self.verbatim_log:
            addLoggerProxy(ctypes.byref(self.callbacks))
        _log_sinks[id(self)] = self
        self.fmu.instantiate(callbacks=self.callbacks, loggingOn=self._logging_on())
        self.state = "instantiated"
        # any pythonfmu FMU, ours or not, can abort this process at exit: see exit_guard
        exit_guard.install(Path(self.fmu.unzipDirectory) / "resources")
        if self.debug_logging is not None:
            self.fmu.setDebugLogging(True, list(self.debug_logging))
        self.fmu.setupExperiment(startTime=0.0, stopTime=stop_time)
        grouped: dict[str, tuple[list[int], list[Any]]] = {}
        for name, value in self.instance.start.items():
            var = self.instance.variable(name)
            kind = "Integer" if var.type == "Enumeration" else var.type
            vrs, values = grouped.setdefault(kind, ([], []))
            vrs.append(var.valueReference)
            values.append(value)
        setters = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                   "Boolean": self.fmu.setBoolean, "String": self.fmu.setString}  # fmt: skip
        for kind, (vrs, values) in grouped.items():
            setters[kind](vrs, values)

    def enter_initialisation(self) -> None:
        """enterInitializationMode: the master may now exchange values with the instance
        (FMI 2.0, section 4.2.4) before :meth:`exit_initialisation`."""
        self._expect("instantiated")
        self.fmu.enterInitializationMode()
        self.state = "initialization"
        self.c = self.fmu.component
        self.handle.value = self.c

    def exit_initialisation(self) -> None:
        """exitInitializationMode (an FMU may compile or load its code here, as AuvPlant
        does, so that its first doStep costs what every other does)."""
        self._expect("initialization")
        self.fmu.exitInitializationMode()
        self.state = "stepping"

    def read_outputs(self) -> None:
        self._expect("initialization", "stepping")
        self.read_reals()
        if self.others:
            self.get_others()

    def ended_simulation(self) -> float | None:
        """After a doStep returned Discard: the time the instance reached if it ended the
        simulation (``fmi2GetBooleanStatus(fmi2Terminated)`` true: FMI 2.0, section
        4.2.3), else None. A Discard whose last logged line is an Error is a failure:
        pythonfmu answers Terminated true after any doStep that returned False."""
        if self.messages and self.messages[-1].startswith(("[Error]", "[Fatal]")):
            return None
        try:
            if self.fmu.getBooleanStatus(fmi2Terminated):
                return float(self.fmu.getRealStatus(fmi2LastSuccessfulTime))
        except Exception:  # a status it cannot give: the Discard stands as a failure
            return None
        return None

    def note_warning(self, function: str, t: float) -> None:
        """``function`` returned fmi2Warning in the step from ``t`` (s): kept among the
        logged messages, as the FMU may log no reason for it."""
        self.messages.append(f"[Warning] {function} returned Warning at t = {seconds(t)} s")
        self.logged += 1

    def partial_step(self) -> float | None:
        """After a doStep's Discard that did not end the simulation: the time (s) the
        instance reached in the step (``fmi2LastSuccessfulTime``), None if it cannot say."""
        try:
            return float(self.fmu.getRealStatus(fmi2LastSuccessfulTime))
        except Exception:  # a status it cannot give
            return None

    def failed(self, status: int) -> None:
        """Record a non-OK status: after Discard the instance may still be terminated,
        after Error only freed, after Fatal not touched at all (FMI 2.0, 4.2.4), nor after
        a number that is no fmi2Status (nothing says what it may still do). Pending
        (a step run asynchronously, which this master does not wait for) is cancelled
        (fmi2CancelStep), after which the instance is only freed."""
        if status == PENDING:
            try:
                self.fmu.cancelStep()
                self.state = "error"
            except Exception:  # it cannot be cancelled: not touched again
                self.state = "fatal"
        elif status == 3:
            self.state = "error"
        elif status not in (*PASSED, DISCARD):
            self.state = "fatal"

    def _terminate(self) -> None:
        """fmi2Terminate; a failure is kept among the messages, and after an Error the
        instance is still freed (FMI 2.0, 4.2.4), after a Fatal or a number out of the
        enum not (:func:`_strict`: fmpy's wrapper raises above fmi2Warning only)."""
        try:
            status = self.fmu.terminate()
        except FMICallException as exc:
            status = exc.status
        if status not in PASSED:
            self.messages.append(f"[{label(status)}] fmi2Terminate returned {label(status)}")
            self.logged += 1
            self.failed(status)
        if self.state == "stepping":
            self.state = "terminated"

    def finish(self) -> None:
        """terminate + freeInstance as far as the state allows; never raises. The fmpy
        object, its library still loaded, waits for this process's next run (not after a
        Fatal status: that instance is never touched again)."""
        try:
            if self.state == "stepping":  # FMI 2.0 allows fmi2Terminate only once initialised
                self._terminate()
            if self.state in ("instantiated", "initialization", "terminated", "error"):
                self.state = "freed"
                self.fmu.fmi2FreeInstance(self.fmu.component)  # the library stays loaded
                self.fmu.component = None
                _idle_libraries.setdefault(self._key, []).append(self.fmu)
            elif self.state == "new":  # never instantiated (or instantiation failed)
                self.state = "freed"
                _idle_libraries.setdefault(self._key, []).append(self.fmu)
        except Exception as exc:  # a failing clean-up must not hide the run's own result
            self.messages.append(f"[clean-up] {exc}")
            self.state = "freed"
        finally:
            if self.state == "freed":
                _log_sinks.pop(id(self), None)


_log_sinks: dict[int, Slave] = {}  # componentEnvironment -> the instance that logs


def _log(env: int | None, _name: bytes, status: int, category: bytes, message: bytes) -> None:
    """The FMUs' logger: keeps warnings and worse per instance, each on one line and shortened
    (:func:`fmu_runtime.log_text.shortened`: an FMU may log megabytes in one message), and
    shows on stderr every message of an instance whose debug logging is on (which ones the
    FMU passes for the categories asked for is the FMU's: FMI 2.0, 2.1.5). A C callback:
    never raises."""
    slave = _log_sinks.get(env or 0)
    if slave is None or (status < 1 and slave.debug_logging is None):
        return
    name = STATUS_LABELS[status] if 0 <= status < len(STATUS_LABELS) else str(status)
    text = (message or b"").decode("utf-8", "replace")
    if slave.verbatim_log:  # a message as written, ours with every % doubled
        text = text.replace("%%", "%")
    text = one_line(shortened(text))
    kind = (category or b"").decode("utf-8", "replace")
    if status >= 1:
        slave.messages.append(f"[{name}] {text}")
        slave.logged += 1
    if slave.debug_logging is not None:  # what the FMU passes for its categories (FMI 2.0)
        with contextlib.suppress(Exception):  # stderr closed or full: the run goes on
            _show(f"{slave.name}: [{name}] {kind}: {text}")


DEBUG_LINES_KEPT = 10_000  # debug-log lines a collected run keeps (collect_debug_log)


class _Collected(threading.local):
    lines: list[str] | None = None  # this thread's run's debug log, while collected
    dropped = 0  # lines past DEBUG_LINES_KEPT


_collected = _Collected()


@contextlib.contextmanager
def collect_debug_log() -> Iterator[list[str]]:
    """Collect the debug-log lines of the runs this thread makes inside the block into
    the list yielded, instead of showing them on stderr (a study's run, whose stderr is a
    worker's). The first :data:`DEBUG_LINES_KEPT` are kept, then one line saying how
    many more there were. The FMUs log on the thread that calls them."""
    lines: list[str] = []
    _collected.lines, _collected.dropped = lines, 0
    try:
        yield lines
    finally:
        if _collected.dropped:
            lines.append(f"({_collected.dropped} more lines of the debug log left out)")
        _collected.lines, _collected.dropped = None, 0


def _show(line: str) -> None:
    """One debug-log line on stderr, above a progress bar if one is drawn (tqdm's write
    clears the bar, writes and draws it again), or into the collected lines
    (:func:`collect_debug_log`)."""
    lines = _collected.lines
    if lines is not None:
        if len(lines) < DEBUG_LINES_KEPT:
            lines.append(line)
        else:
            _collected.dropped += 1
        return
    write(line, sys.stderr)


def one_line(message: str) -> str:
    """An FMU's logged ``message`` as one line: its lines joined by " | " (pythonfmu logs
    an exception in the FMU as the failed call, then the exception, on a line of its own;
    every error of a run is one line)."""
    return " | ".join(line.strip() for line in message.splitlines() if line.strip())


_LOGGER = fmi2CallbackLoggerTYPE(_log)


def _formats_messages(folder: Path) -> bool:
    """Whether the FMU extracted in ``folder`` passes its logged messages as printf
    formats with their arguments (FMI 2.0, 2.1.5), for fmpy's logger proxy to format:
    every FMU but one of pythonfmu's own binary (``resources/slavemodule.txt``, not our
    runtime), which passes a Python message as the format, its % signs as written and no
    argument, so that "50% done" read an argument never passed (garbage, and a ``%s`` or
    ``%n`` a crash)."""
    from fmpy import platform

    pythonfmu = (folder / "resources" / "slavemodule.txt").is_file()
    return not pythonfmu or native.loader_in_folder(folder, platform)


def describe(slave: Slave, function: str, status: int, t: float) -> str:
    """One line: which call of which instance failed, when, what it means
    (:func:`_meaning`) and the FMU's logged reason."""
    meaning = _meaning(slave, function, status, t)
    said = label(status)
    when = f"at t = {seconds(t)} s"
    return f"{slave.name}: {function} returned {said} {when}{meaning}{reasons(slave)}"


def label(status: int) -> str:
    """An fmi2Status by name ("Error"), or a number no fmi2Status has as that number."""
    if 0 <= status < len(STATUS_LABELS):
        return STATUS_LABELS[status]
    return f"{status} (not an fmi2Status)"


def _meaning(slave: Slave, function: str, status: int, t: float) -> str:
    """What a failed call at ``t`` (s) means beyond its status ("" if nothing): a doStep's
    Discard that did not end the simulation (a partial step, and the time reached, or a
    step refused before it started: the FMU still at ``t``), a doStep's
    Pending (called after :meth:`Slave.failed` cancelled it), an FMU state the adaptive
    algorithm could not save or restore."""
    if function == "fmi2DoStep" and status == PENDING:
        done = "the step was cancelled" if slave.state == "error" else "it could not be cancelled"
        return (": the FMU runs its step asynchronously, which this master does not wait "
                f"for; {done}")  # fmt: skip
    if function == "fmi2DoStep" and status == DISCARD:
        reached = slave.partial_step()
        if reached is None:
            return ""
        if reached <= t:  # fmi2LastSuccessfulTime at the step's start: none of it taken
            return f": the step was refused, the FMU still at t = {seconds(reached)} s"
        return f": a partial step, to t = {seconds(reached)} s"
    if function in ("fmi2GetFMUstate", "fmi2SetFMUstate"):
        return (": algorithm 'adaptive' saves every instance's state to roll rejected steps "
                "back; use 'gauss-seidel' or 'jacobi' with a fixed step")  # fmt: skip
    return ""


def reasons(slave: Slave) -> str:
    """The FMU's last logged reason(s), one line."""
    lines = [m for m in slave.messages if not m.startswith("[Warning]")][-3:]
    return (": " + " | ".join(lines)) if lines else " (the FMU logged no reason)"


# --- loaded FMU libraries, reused by the runs of one process -------------------------------

# (unzip folder, model identifier, guid, instance name) -> FMU2Slave objects whose
# instance was freed (a Fatal one is never put back). Written by hand: fmpy loads the
# library and resolves its ~40 functions with ctypes in every FMU2Slave (~3 ms, as long as
# a tenth of a 20 s run's set-up in a study), and its freeInstance unloads the library
# again. Reusing the object skips both; a new instance is instantiated in it as FMI 2.0
# allows any number of instantiate/freeInstance cycles per loaded library.
_idle_libraries: dict[tuple[str, str, str, str], list[FMU2Slave]] = {}


def _library(key: tuple[str, str, str, str]) -> FMU2Slave:
    """An fmpy ``FMU2Slave`` with the library loaded and no instance: an idle one of an
    earlier run, else a new one."""
    try:
        return _idle_libraries[key].pop()  # atomic: two runs in threads never share one
    except (KeyError, IndexError):
        pass
    unzip_dir, model_identifier, guid, instance_name = key
    cwd = os.getcwd()
    try:
        return _strict(
            FMU2Slave(
                guid=guid,
                unzipDirectory=unzip_dir,
                modelIdentifier=model_identifier,
                instanceName=instance_name,
            )
        )
    except Exception as exc:  # fmpy raises a plain Exception, in the binary's folder
        os.chdir(cwd)  # fmpy changes the working directory to load it and leaves it there
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CosimError(
            f"{instance_name}: cannot load the binary of {model_identifier}: {reason}"
        ) from None


def _strict(fmu: FMU2Slave) -> FMU2Slave:
    """``fmu`` whose fmpy wrappers of the calls returning an fmi2Status raise
    FMICallException for a number below fmi2OK too (fmpy's raise above fmi2Warning only:
    -1 from fmi2EnterInitializationMode, a start value's setter or fmi2SetFMUstate passed
    as OK), so that every call the master makes through fmpy, at set-up and at a state's
    restore as in a step, stops at a number that is no fmi2Status (:data:`PASSED`)."""
    for name, wrapper in list(vars(fmu).items()):
        function = getattr(fmu.dll, name, None) if name.startswith("fmi2") else None
        if function is not None and function.restype is fmi2Status:
            setattr(fmu, name, _no_negative_status(name, wrapper))
    return fmu


def _no_negative_status(name: str, wrapper: Callable[..., int]) -> Callable[..., int]:
    """fmpy's ``wrapper`` of the C function ``name``, raising on a status below fmi2OK."""

    def call(*args: Any) -> int:
        status = wrapper(*args)
        if status < 0:
            raise FMICallException(function=name, status=status)
        return status

    return call


# --- unzipped FMUs, one folder per FMU content per process ---------------------------------

_digests: dict[tuple[Path, int, int], str] = {}  # (file, mtime ns, size) -> its SHA-256
_unzipped_dirs: dict[str, Path] = {}  # SHA-256 of an FMU file -> where it was extracted
_shared_dirs: dict[str, Path] = {}  # SHA-256 -> where another process extracted it
_file_lists: dict[Path, tuple[str, ...]] = {}  # an extraction -> the paths of its files
_guids: dict[Path, str] = {}  # an extraction -> the GUID of its modelDescription.xml


def share_unzipped(digest: str, folder: Path) -> None:
    """Use ``folder``, where another process (a local study's client) extracted the FMU
    whose file has the SHA-256 ``digest``, instead of extracting it in this one: the
    extraction, and the compiling of the Python code it ships, are done once for every
    worker. The folder stays that process's to remove; a folder gone is not used."""
    _shared_dirs[digest] = folder


def unzipped(fmu_path: Path) -> Path:
    """Extract an FMU once per process and content (pythonfmu keeps its modules imported
    anyway): another copy of the same file -- a study's FMUs, uploaded to a worker again
    for each study -- reuses the extraction, and with it the loaded library
    (:func:`_library`). A file changed in place is extracted again."""
    status = fmu_path.stat()
    key = (fmu_path.resolve(), status.st_mtime_ns, status.st_size)
    digest = _digests.get(key)
    if digest is None:
        digest = _digests[key] = hashlib.sha256(fmu_path.read_bytes()).hexdigest()
    shared = _shared_dirs.get(digest)
    if shared is not None and _whole(shared, fmu_path):
        return shared
    own = _unzipped_dirs.get(digest)
    if own is None or not _whole(own, fmu_path):
        # in this process's scratch folder: removed as the process ends, or by the next
        # process if this one is killed outright (cosim.scratch)
        _unzipped_dirs[digest] = _extracted(fmu_path)
    return _unzipped_dirs[digest]


def _check_same_fmu(instance: Instance, unzip_dir: Path) -> None:
    """Refuse an extraction whose GUID is not that of the description ``instance`` was
    loaded with: the file was replaced in between (another process built it again from
    changed sources), and its code would be driven through the old description's value
    references. Raises CosimError naming the file."""
    found, loaded = extracted_guid(unzip_dir), instance.model_description.guid
    if found != loaded:
        raise CosimError(
            f"{instance.name}: {instance.fmu_path} changed after the scenario was loaded "
            f"(its GUID is {found!r}, the scenario loaded {loaded!r}; another process built "
            "it again): load the scenario again (run the command again)"
        )


def extracted_guid(folder: Path) -> str:
    """The ``guid`` of the modelDescription.xml extracted into ``folder`` ("" if none),
    read once per extraction (its files do not change)."""
    guid = _guids.get(folder)
    if guid is None:
        with open(folder / "modelDescription.xml", "rb") as description:
            guid = _guids[folder] = root_attributes(description).get("guid", "")
    return guid


def _whole(folder: Path, fmu_path: Path) -> bool:
    """Whether ``folder`` still holds every file of the FMU extracted into it: a
    long-lived process (a notebook's kernel) outlives files of its temporary folder (a
    cleaner of old files in /tmp), and a folder missing one made every later run fail.
    One ``os.path.exists`` a file (~0.2 ms for our FMUs' ~120 files, once a run)."""
    paths = _file_lists.get(folder)
    if paths is None:
        with zipfile.ZipFile(fmu_path) as archive:
            names = [n for n in archive.namelist() if not n.endswith("/")]
        paths = _file_lists[folder] = tuple(str(folder / name) for name in names)
    return all(map(os.path.exists, paths))


def _extracted(fmu_path: Path) -> Path:
    """``fmu_path`` extracted into a new folder in this process's scratch folder
    (:func:`cosim.scratch.process_folder`, in ``TMPDIR``). An extraction the
    system refuses (a full disk, a file size limit: ``ulimit -f``) is a :class:`CosimError`
    naming the FMU, the temporary folder and why, and the partly extracted folder goes; an
    FMU that declares more bytes than the limit or the free space is refused before a byte
    is written (:func:`cosim.fmus.interface.extract_fmu`)."""
    try:
        folder = Path(tempfile.mkdtemp(dir=process_folder()))
    except OSError as exc:
        raise _cannot_extract(fmu_path, exc) from None
    try:
        extract_fmu(fmu_path, folder)
    except (OSError, FmuInterfaceError) as exc:
        shutil.rmtree(folder, ignore_errors=True)
        if isinstance(exc, FmuInterfaceError):
            raise
        raise _cannot_extract(fmu_path, exc) from None
    return folder


def _cannot_extract(fmu_path: Path, exc: OSError) -> CosimError:
    """Why the system refused to extract ``fmu_path`` into the temporary folder (the
    file-size limit named where it was that: :func:`cosim.limits.unwritten`)."""
    return CosimError(
        f"cannot extract {fmu_path} into the temporary folder {tempfile.gettempdir()} "
        f"(TMPDIR): {unwritten(exc)}"
    )


def _checked(fmu: Any, name: str, warned: Callable[[str, float], None]) -> Callable[..., int]:
    """The FMU library's C function ``name`` (fmpy set its argument types) behind one
    status check, as fmpy's wrapper does it: a status worse than fmi2Warning raises
    FMICallException(name, status), as a number out of the enum does (:data:`PASSED`);
    fmi2Warning is told to ``warned(name, t)``, t (s) the
    call's second argument. fmpy's wrapper takes two Python frames and a lookup per call
    (~1.5 us), several times a step; this one frame."""
    function = getattr(fmu.dll, name)

    def call(*args: Any) -> int:
        status: int = function(*args)
        if status:
            if status != WARNING:
                raise FMICallException(function=name, status=status)
            warned(name, float(args[1]))
        return status

    return call


def _c_function(fmu: Any, name: str) -> Any:
    """A new function object of the FMU library's C function ``name`` with no argument
    types (fmpy's own objects keep theirs): called with ctypes objects only, which ctypes
    passes as they are (a plain Python int would go as a C int, a float not at all)."""
    function = fmu.dll[name]
    function.restype = ctypes.c_int  # fmi2Status
    return function


def _hot_calls(slave: Slave) -> tuple[Callable[[], None], Callable[[], None], Callable[..., None]]:
    """The stepping loop's calls of ``slave``, every argument but the times bound once:
    ``put_inputs()`` (fmi2SetReal of the input buffer), ``read_reals()`` (fmi2GetReal into
    the output view) and ``advance(t, h)`` (fmi2DoStep from ``t`` over ``h`` s, then the
    outputs read, the Integer and Boolean ones too). A status worse than fmi2Warning raises
    FMICallException naming the function, as fmpy's wrappers do, and so does a number
    out of the enum; a doStep's fmi2Warning
    is kept among the messages (:meth:`Slave.note_warning`).

    Written by hand: fmpy's wrappers take two Python frames a call and convert every
    argument through its declared type (~1 us a call, eight calls a step of two
    instances with input derivatives); these pass ctypes objects made once to function
    objects without declared types (~0.3 us a call)."""
    handle, fmu = slave.handle, slave.fmu
    set_real, get_real = _c_function(fmu, "fmi2SetReal"), _c_function(fmu, "fmi2GetReal")
    do_step = _c_function(fmu, "fmi2DoStep")
    in_vrs, n_in, in_ptr = slave.input_vrs, ctypes.c_size_t(slave.n_inputs), slave.input_ptr
    out_vrs, n_out, out_ptr = slave.output_vrs, ctypes.c_size_t(slave.n_outputs), slave.output_ptr
    double, prior = ctypes.c_double, ctypes.c_int(1)  # noSetFMUStatePriorToCurrentPoint
    others = slave.get_others if slave.others else None
    warned = slave.note_warning

    def put_inputs() -> None:
        status = set_real(handle, in_vrs, n_in, in_ptr)
        if status and status != WARNING:
            raise FMICallException(function="fmi2SetReal", status=status)

    def read_reals() -> None:
        status = get_real(handle, out_vrs, n_out, out_ptr)
        if status and status != WARNING:
            raise FMICallException(function="fmi2GetReal", status=status)

    def advance(t: float, h: float) -> None:
        status = do_step(handle, double(t), double(h), prior)
        if status:
            if status != WARNING:
                raise FMICallException(function="fmi2DoStep", status=status)
            warned("fmi2DoStep", t)
        status = get_real(handle, out_vrs, n_out, out_ptr)
        if status and status != WARNING:
            raise FMICallException(function="fmi2GetReal", status=status)
        if others is not None:
            others()

    return put_inputs, read_reals, advance
