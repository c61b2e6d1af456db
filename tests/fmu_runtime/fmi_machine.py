"""A stateful Hypothesis fuzzer of our FMUs through ctypes: random sequences of FMI 2.0
calls on the plant and the autopilot loaded in this process, with arguments valid and
hostile (unknown, duplicated and mistyped value references, ``nvr`` 0 with NULL arrays,
huge ``nvr``, NaN and infinite times and values, states of another FMU, serialised
states garbled, cut or taken before a reset), each answer checked:

* every status is one of fmi2OK .. fmi2Fatal;
* a Discard, Error or Fatal comes with at least one log line of the call saying why;
* an fmi2GetReal answered fmi2OK gives finite values;
* a step is answered fmi2OK only after initialisation (and before fmi2Terminate);
* a state of another FMU, a freed state and garbled bytes are never answered fmi2OK,
  and intact serialised bytes of this FMU deserialise.

The process surviving is the caller's check (run it in a fresh process):
``python fmi_machine.py PLANT AUTOPILOT EXAMPLES STEPS`` (each an .fmu or an extraction)
replays the sequences that found defects, then prints how often each function answered
each status and ``fuzz: ok``, or raises with Hypothesis's shortest failing sequence.
"""

from __future__ import annotations

import ctypes
import math
import sys
import tempfile
import zipfile
from collections import Counter
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from dataclasses import dataclass, field
from pathlib import Path

from fmpy import read_model_description
from fmpy.fmi2 import (
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    free,
)
from fmpy.logging import addLoggerProxy
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import (
    Bundle,
    RuleBasedStateMachine,
    consumes,
    rule,
    run_state_machine_as_test,
)

OK, WARNING, DISCARD, ERROR, FATAL = range(5)
TYPES = {"Real": c_double, "Integer": c_int, "Boolean": c_int, "String": c_char_p}
HUGE = 200_000  # value references in one call: far more than any FMU has
LOG: list[tuple[int, str]] = []  # every log line of every instance, in order
ANSWERS: Counter[tuple[str, int]] = Counter()  # (function, status): how often


def _on_log(environment, instance, status, category, message) -> None:
    LOG.append((int(status), (message or b"").decode("utf-8", "replace")))


CALLBACKS = fmi2CallbackFunctions()
CALLBACKS.logger = fmi2CallbackLoggerTYPE(_on_log)
CALLBACKS.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
CALLBACKS.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
addLoggerProxy(byref(CALLBACKS))

SIGNATURES = {
    "fmi2Instantiate": (c_void_p, [c_char_p, c_int, c_char_p, c_char_p, c_void_p, c_int, c_int]),
    "fmi2FreeInstance": (None, [c_void_p]),
    "fmi2SetupExperiment": (c_int, [c_void_p, c_int, c_double, c_double, c_int, c_double]),
    "fmi2EnterInitializationMode": (c_int, [c_void_p]),
    "fmi2ExitInitializationMode": (c_int, [c_void_p]),
    "fmi2Terminate": (c_int, [c_void_p]),
    "fmi2Reset": (c_int, [c_void_p]),
    "fmi2DoStep": (c_int, [c_void_p, c_double, c_double, c_int]),
    "fmi2GetFMUstate": (c_int, [c_void_p, POINTER(c_void_p)]),
    "fmi2SetFMUstate": (c_int, [c_void_p, c_void_p]),
    "fmi2FreeFMUstate": (c_int, [c_void_p, POINTER(c_void_p)]),
    "fmi2SerializedFMUstateSize": (c_int, [c_void_p, c_void_p, POINTER(c_size_t)]),
    "fmi2SerializeFMUstate": (c_int, [c_void_p, c_void_p, c_char_p, c_size_t]),
    "fmi2DeSerializeFMUstate": (c_int, [c_void_p, c_char_p, c_size_t, POINTER(c_void_p)]),
    "fmi2GetRealStatus": (c_int, [c_void_p, c_int, POINTER(c_double)]),
    "fmi2GetStatus": (c_int, [c_void_p, c_int, POINTER(c_int)]),
    "fmi2GetIntegerStatus": (c_int, [c_void_p, c_int, POINTER(c_int)]),
    "fmi2GetBooleanStatus": (c_int, [c_void_p, c_int, POINTER(c_int)]),
    "fmi2GetStringStatus": (c_int, [c_void_p, c_int, POINTER(c_char_p)]),
    "fmi2CancelStep": (c_int, [c_void_p]),
    "fmi2SetDebugLogging": (c_int, [c_void_p, c_int, c_size_t, POINTER(c_char_p)]),
    "fmi2SetRealInputDerivatives": (c_int, [c_void_p, c_void_p, c_size_t, c_void_p, c_void_p]),
    "fmi2GetRealOutputDerivatives": (c_int, [c_void_p, c_void_p, c_size_t, c_void_p, c_void_p]),
}
for _kind, _ctype in TYPES.items():
    for _verb in ("Get", "Set"):
        SIGNATURES[f"fmi2{_verb}{_kind}"] = (c_int, [c_void_p, c_void_p, c_size_t, c_void_p])


@dataclass
class Fmu:
    """One FMU's binary loaded from its own extraction, and its variables."""

    name: str
    guid: str
    resources: bytes
    dll: ctypes.CDLL
    refs: dict[str, list[int]] = field(default_factory=dict)  # value references by type


def load(path: str, folder: Path) -> Fmu:
    """The FMU at ``path`` (an .fmu, extracted into ``folder``, or an extraction) and its
    binary loaded."""
    md = read_model_description(path)
    name = md.coSimulation.modelIdentifier
    extraction = Path(path)
    if not extraction.is_dir():
        extraction = folder / name
        with zipfile.ZipFile(path) as archive:
            archive.extractall(extraction)
    dll = ctypes.CDLL(str(extraction / "binaries" / "linux64" / f"{name}.so"))
    for function, (restype, argtypes) in SIGNATURES.items():
        getattr(dll, function).restype = restype
        getattr(dll, function).argtypes = argtypes
    fmu = Fmu(name, md.guid, (extraction / "resources").as_uri().encode(), dll)
    for kind in TYPES:
        fmu.refs[kind] = [v.valueReference for v in md.modelVariables if v.type == kind]
    return fmu


@dataclass
class Instance:
    """A live component, the FMU it is of and the host's model of its phase."""

    fmu: Fmu
    pointer: int
    phase: str = "instantiated"  # instantiated, initialisation, stepping, terminated


@dataclass
class State:
    """An FMU state a call gave, the FMU that took it and whether it is freed."""

    fmu: Fmu
    pointer: int
    phase: str
    freed: bool = False


FMUS: list[Fmu] = []
TIMES = st.one_of(
    st.sampled_from([0.0, -0.0, -1.0, 1e-300, 0.1, 1e17, 1.7e308]),
    st.floats(allow_nan=True, allow_infinity=True),
)
STEPS = st.one_of(
    st.sampled_from([0.01, 0.1, 1.0]),
    st.sampled_from([0.0, -0.0, -0.1, 1e-300, 1e308, 1e6]),
    st.floats(allow_nan=True, allow_infinity=True),
)
STRINGS = st.one_of(
    st.none(),
    st.sampled_from([b"", b"remus100", b"%s%n%s", b"\xff\xfe", b"0,0,0;100,0,0", b"x" * 10000]),
    st.text(max_size=40).map(lambda s: s.replace("\0", "").encode()),
)
VALUES = {
    "Real": st.floats(allow_nan=True, allow_infinity=True),
    "Integer": st.integers(-(2**31), 2**31 - 1),
    "Boolean": st.sampled_from([0, 1, 2, -1, 2**31 - 1]),
    "String": STRINGS,
}


def references(fmu: Fmu, kind: str) -> st.SearchStrategy[list[int]]:
    """Value references for a call on ``kind``: its own, the other types', unknown ones."""
    own = st.sampled_from(fmu.refs[kind]) if fmu.refs[kind] else st.just(0)
    anyone = st.sampled_from(sorted(r for refs in fmu.refs.values() for r in refs))
    unknown = st.sampled_from([10_000, 2**31, 2**32 - 1])
    mixed = st.lists(st.one_of(own, anyone, unknown), max_size=6)
    return st.one_of(st.lists(own, min_size=1, max_size=6), mixed, st.just([]))


def array(ctype, values: list) -> ctypes.Array | None:
    """A C array of ``values`` (NULL for none)."""
    return (ctype * len(values))(*values) if values else None


class FmiMachine(RuleBasedStateMachine):
    """Random FMI 2.0 call sequences on the plant and the autopilot (see the module)."""

    instances = Bundle("instances")
    states = Bundle("states")
    blobs = Bundle("blobs")

    def __init__(self) -> None:
        super().__init__()
        self.alive: list[Instance] = []
        self.taken: list[State] = []

    def call(self, fmu: Fmu, function: str, *args, component: bool = True) -> int:
        """``function(*args)``: its status, checked in range and logged when not OK."""
        start = len(LOG)
        status = getattr(fmu.dll, function)(*args)
        assert status in range(5), f"{function} answered status {status}"
        ANSWERS[function, status] += 1
        if status >= DISCARD and component:
            assert len(LOG) > start, f"{function} answered {status} with no log line"
        return status

    @rule(target=instances, which=st.integers(0, 2), good_guid=st.booleans(),
          ready=st.sampled_from([True, True, False]))  # fmt: skip
    def instantiate(self, which: int, good_guid: bool, ready: bool):
        """A new instance (at most three alive), initialised at once if ``ready``."""
        fmu = FMUS[which % len(FMUS)]
        if len(self.alive) >= 3:
            return None
        guid = fmu.guid.encode() if good_guid else b"{not-this-fmu}"
        name = f"{fmu.name}-{len(self.taken)}".encode()
        pointer = fmu.dll.fmi2Instantiate(name, 1, guid, fmu.resources, byref(CALLBACKS), 0, 1)
        assert bool(pointer) == good_guid, f"instantiate with guid {guid!r} gave {pointer}"
        if not pointer:
            return None
        instance = Instance(fmu, pointer)
        self.alive.append(instance)
        if ready:
            self.initialise(instance)
        return instance

    def live(self, instance) -> bool:
        return isinstance(instance, Instance) and instance in self.alive

    @rule(instance=consumes(instances))
    def free_instance(self, instance):
        if self.live(instance):
            instance.fmu.dll.fmi2FreeInstance(instance.pointer)
            self.alive.remove(instance)

    @rule(instance=instances, start=TIMES, stop=st.one_of(st.none(), TIMES))
    def setup_experiment(self, instance, start: float, stop: float | None):
        if self.live(instance):
            args = (0, 0.0, start, stop is not None, 0.0 if stop is None else stop)
            status = self.call(instance.fmu, "fmi2SetupExperiment", instance.pointer, *args)
            if instance.phase != "instantiated":
                assert status != OK, f"setupExperiment in {instance.phase} answered OK"

    @rule(instance=instances)
    def initialise(self, instance):
        """setupExperiment, enter and exit initialisation mode: the valid way to stepping."""
        if not self.live(instance):
            return
        fmu, pointer = instance.fmu, instance.pointer
        for function, args in (("fmi2SetupExperiment", (0, 0.0, 0.0, 0, 0.0)),
                               ("fmi2EnterInitializationMode", ()),
                               ("fmi2ExitInitializationMode", ())):  # fmt: skip
            if self.call(fmu, function, pointer, *args) != OK:
                return
        instance.phase = "stepping"

    @rule(instance=instances, function=st.sampled_from(["enter", "exit", "terminate", "reset"]))
    def change_phase(self, instance, function: str):
        if not self.live(instance):
            return
        names = {"enter": "EnterInitializationMode", "exit": "ExitInitializationMode",
                 "terminate": "Terminate", "reset": "Reset"}  # fmt: skip
        status = self.call(instance.fmu, f"fmi2{names[function]}", instance.pointer)
        after = {"enter": "initialisation", "exit": "stepping", "terminate": "terminated",
                 "reset": "instantiated"}[function]  # fmt: skip
        if status == OK:
            instance.phase = after

    @rule(instance=instances, t=TIMES, h=STEPS, contiguous=st.sampled_from([True, True, False]),
          final=st.sampled_from([0, 1, 2]))  # fmt: skip
    def do_step(self, instance, t: float, h: float, contiguous: bool, final: int):
        """A step from the FMU's time (``contiguous``) or ``t``; ``final`` is
        noSetFMUStatePriorToCurrentPoint (2: neither fmi2False nor fmi2True)."""
        if not self.live(instance):
            return
        if contiguous:
            time = c_double()
            instance.fmu.dll.fmi2GetRealStatus(instance.pointer, 2, byref(time))
            t = time.value
        before = self.reals(instance)
        status = self.call(instance.fmu, "fmi2DoStep", instance.pointer, t, h, final)
        if status == OK:
            assert instance.phase == "stepping", f"doStep in {instance.phase} answered OK"
            assert math.isfinite(t + h) and h > 0, f"doStep({t}, {h}) answered OK"
            time = c_double()
            instance.fmu.dll.fmi2GetRealStatus(instance.pointer, 2, byref(time))
            assert time.value == t + h, f"doStep({t}, {h}) answered OK, time {time.value}"
        if status == ERROR and before is not None:
            after = self.reals(instance)
            assert after == before, f"doStep({t}, {h}) refused, values {before} -> {after}"

    def reals(self, instance: Instance) -> list[float] | None:
        """Every Real of ``instance``, or None if they cannot be read (no status checks:
        the host's own look)."""
        refs = instance.fmu.refs["Real"]
        out = (c_double * len(refs))()
        status = instance.fmu.dll.fmi2GetReal(instance.pointer, array(c_uint, refs), len(refs), out)
        return list(out) if status == OK else None

    @rule(instance=instances, kind=st.sampled_from(sorted(TYPES)), data=st.data())
    def get_values(self, instance, kind: str, data):
        if not self.live(instance):
            return
        refs = data.draw(references(instance.fmu, kind))
        out = (TYPES[kind] * len(refs))() if refs else None
        status = self.call(instance.fmu, f"fmi2Get{kind}", instance.pointer,
                           array(c_uint, refs), len(refs), out)  # fmt: skip
        if status == OK and kind == "Real" and refs:
            assert all(math.isfinite(v) for v in out), f"getReal{refs} gave {list(out)}"
        if status == OK and kind == "String" and refs:
            assert all(v is not None for v in out), f"getString{refs} gave {list(out)}"

    @rule(instance=instances, kind=st.sampled_from(["", "Real", "Integer", "Boolean", "String"]),
          which=st.sampled_from([0, 1, 2, 3, 4, 5, -1, 2**31 - 1]))  # fmt: skip
    def get_status(self, instance, kind: str, which: int):
        """fmi2Get*Status of a kind known (fmi2DoStepStatus .. fmi2Terminated) or not."""
        if not self.live(instance):
            return
        out = {"Real": c_double, "String": c_char_p}.get(kind, c_int)()
        status = self.call(instance.fmu, f"fmi2Get{kind}Status", instance.pointer, which,
                           byref(out))  # fmt: skip
        if status == OK and kind == "Real":
            assert math.isfinite(out.value), f"getRealStatus({which}) gave {out.value}"

    @rule(instance=instances, output=st.booleans(), data=st.data(),
          orders=st.lists(st.sampled_from([1, 0, 2, 3, -1]), min_size=1, max_size=4))  # fmt: skip
    def derivatives(self, instance, output: bool, data, orders: list[int]):
        """fmi2SetRealInputDerivatives / fmi2GetRealOutputDerivatives of any order."""
        if not self.live(instance):
            return
        refs = data.draw(st.lists(st.sampled_from(instance.fmu.refs["Real"] + [99_999]),
                                  min_size=len(orders), max_size=len(orders)))  # fmt: skip
        values = data.draw(st.lists(VALUES["Real"], min_size=len(orders), max_size=len(orders)))
        function = "fmi2GetRealOutputDerivatives" if output else "fmi2SetRealInputDerivatives"
        buffer = array(c_double, values)
        status = self.call(instance.fmu, function, instance.pointer, array(c_uint, refs),
                           len(refs), array(c_int, orders), buffer)  # fmt: skip
        if status == OK and output:
            assert all(math.isfinite(v) for v in buffer), f"{function} gave {list(buffer)}"

    @rule(instance=instances, on=st.sampled_from([0, 1, 7]),
          categories=st.lists(st.one_of(st.none(), STRINGS), max_size=3))  # fmt: skip
    def debug_logging(self, instance, on: int, categories: list):
        if self.live(instance):
            self.call(instance.fmu, "fmi2SetDebugLogging", instance.pointer, on,
                      len(categories), array(c_char_p, categories))  # fmt: skip

    @rule(instance=instances)
    def cancel_step(self, instance):
        if self.live(instance):
            self.call(instance.fmu, "fmi2CancelStep", instance.pointer)

    @rule(instance=instances, kind=st.sampled_from(sorted(TYPES)), get=st.booleans(),
          n=st.sampled_from([1, 3]), null=st.sampled_from(["references", "values"]))  # fmt: skip
    def null_arrays(self, instance, kind: str, get: bool, n: int, null: str):
        """n value references with a NULL array of references or of values."""
        if not self.live(instance):
            return
        refs = None if null == "references" else array(c_uint, instance.fmu.refs[kind][:1] * n)
        values = None if null == "values" else (TYPES[kind] * n)()
        status = self.call(instance.fmu, f"fmi2{'Get' if get else 'Set'}{kind}",
                           instance.pointer, refs, n, values)  # fmt: skip
        assert status != OK, f"{kind} with {n} references and NULL {null} answered OK"

    @rule(instance=instances, kind=st.sampled_from(sorted(TYPES)), data=st.data())
    def set_values(self, instance, kind: str, data):
        if not self.live(instance):
            return
        refs = data.draw(references(instance.fmu, kind))
        values = data.draw(st.lists(VALUES[kind], min_size=len(refs), max_size=len(refs)))
        self.call(instance.fmu, f"fmi2Set{kind}", instance.pointer,
                  array(c_uint, refs), len(refs), array(TYPES[kind], values))  # fmt: skip

    @rule(instance=instances, kind=st.sampled_from(sorted(TYPES)), get=st.booleans(),
          known=st.booleans())  # fmt: skip
    def huge_call(self, instance, kind: str, get: bool, known: bool):
        """``HUGE`` value references in one call (one known or unknown, repeated)."""
        if not self.live(instance):
            return
        ref = instance.fmu.refs[kind][0] if known and instance.fmu.refs[kind] else 123_456
        refs = (c_uint * HUGE)(*([ref] * HUGE))
        values = (TYPES[kind] * HUGE)()
        if not get and kind == "String":
            values = (c_char_p * HUGE)(*([b"remus100"] * HUGE))
        verb = "Get" if get else "Set"
        self.call(instance.fmu, f"fmi2{verb}{kind}", instance.pointer, refs, HUGE, values)

    @rule(target=states, instance=instances)
    def get_state(self, instance):
        if not self.live(instance):
            return None
        pointer = c_void_p()
        status = self.call(instance.fmu, "fmi2GetFMUstate", instance.pointer, byref(pointer))
        if status != OK:
            return None
        state = State(instance.fmu, pointer.value, instance.phase)
        self.taken.append(state)
        return state

    def same_address_alive(self, state: State) -> bool:
        return any(
            s.pointer == state.pointer and not s.freed and s is not state for s in self.taken
        )

    @rule(instance=instances, state=states)
    def set_state(self, instance, state):
        if not self.live(instance) or state is None:
            return
        status = self.call(instance.fmu, "fmi2SetFMUstate", instance.pointer, state.pointer)
        if state.freed and not self.same_address_alive(state):
            assert status != OK, "a freed state was set with OK"
        elif state.fmu is not instance.fmu:
            assert status != OK, f"a state of {state.fmu.name} set on {instance.fmu.name} with OK"
        elif status == OK:
            instance.phase = state.phase

    @rule(instance=instances, state=states)
    def free_state(self, instance, state):
        if not self.live(instance) or state is None or state.freed:
            return
        pointer = c_void_p(state.pointer)
        status = self.call(instance.fmu, "fmi2FreeFMUstate", instance.pointer, byref(pointer))
        if status == OK:
            state.freed = True

    @rule(target=blobs, instance=instances, state=states)
    def serialize(self, instance, state):
        if not self.live(instance) or state is None or state.freed:
            return None
        size = c_size_t()
        fmu = instance.fmu
        if self.call(fmu, "fmi2SerializedFMUstateSize", instance.pointer, state.pointer,
                     byref(size)) != OK:  # fmt: skip
            return None
        buffer = ctypes.create_string_buffer(size.value)
        if self.call(fmu, "fmi2SerializeFMUstate", instance.pointer, state.pointer, buffer,
                     size.value) != OK:  # fmt: skip
            return None
        return (state.fmu, state.phase, buffer.raw)

    @rule(target=states, instance=instances, blob=blobs,
          garble=st.sampled_from(["intact", "cut", "extended", "flipped", "garbage"]),
          data=st.data())  # fmt: skip
    def deserialize(self, instance, blob, garble: str, data):
        if not self.live(instance) or blob is None:
            return None
        fmu, phase, raw = blob
        raw = garbled(raw, garble, data)
        pointer = c_void_p()
        status = self.call(instance.fmu, "fmi2DeSerializeFMUstate", instance.pointer,
                           raw, len(raw), byref(pointer))  # fmt: skip
        if garble == "intact" and fmu is instance.fmu:
            assert status == OK, "intact serialised bytes of this FMU refused"
        if garble in ("cut", "garbage") or fmu is not instance.fmu:
            assert status != OK, f"{garble} bytes of {fmu.name} deserialised with OK"
        if status != OK:
            return None
        state = State(instance.fmu, pointer.value, phase)
        self.taken.append(state)
        return state

    def teardown(self) -> None:
        for state in self.taken:
            if not state.freed and self.alive:
                owner = next((i for i in self.alive if i.fmu is state.fmu), None)
                if owner is not None:
                    owner.fmu.dll.fmi2FreeFMUstate(owner.pointer, byref(c_void_p(state.pointer)))
        for instance in self.alive:
            instance.fmu.dll.fmi2FreeInstance(instance.pointer)


def garbled(raw: bytes, how: str, data) -> bytes:
    """``raw`` cut short, extended, with one byte changed, or replaced by random bytes."""
    if how == "cut":
        return raw[: data.draw(st.integers(0, max(len(raw) - 1, 0)))]
    if how == "extended":
        return raw + data.draw(st.binary(min_size=1, max_size=64))
    if how == "flipped" and raw:
        at = data.draw(st.integers(0, len(raw) - 1))
        return raw[:at] + bytes([raw[at] ^ 0xFF]) + raw[at + 1 :]
    if how == "garbage":
        return data.draw(st.binary(min_size=0, max_size=len(raw) + 16))
    return raw


def replay_found() -> None:
    """The sequences this machine found defects with, replayed as they shrank: the
    autopilot's serialised state, intact, deserialised by the plant (pythonfmu's binary
    answered fmi2OK)."""
    machine = FmiMachine()
    autopilot = machine.instantiate(which=1, good_guid=True, ready=True)
    plant = machine.instantiate(which=0, good_guid=True, ready=True)
    blob = machine.serialize(autopilot, machine.get_state(autopilot))
    machine.deserialize(plant, blob, "intact", None)
    machine.teardown()


def main(plant: str, autopilot: str, examples: int, steps: int) -> None:
    """Replay the sequences that found defects, then run the machine ``examples`` times
    of up to ``steps`` calls, derandomised."""
    profile = settings(max_examples=examples, stateful_step_count=steps, deadline=None,
                       database=None, derandomize=True, print_blob=True,
                       suppress_health_check=list(HealthCheck))  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="fmi-machine-") as folder:
        FMUS.extend(load(path, Path(folder)) for path in (plant, autopilot))
        replay_found()
        run_state_machine_as_test(FmiMachine, settings=profile)
    for (function, status), count in sorted(ANSWERS.items()):
        print(f"{function} {status} {count}")
    print("fuzz: ok", flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
