"""SafeSlave's rules, called in-process on a small subclass (no FMU build needed): no
callback raises, bad writes are refused and reported, FMU state round-trips exactly."""

from __future__ import annotations

import gc
import math
import weakref
from typing import ClassVar

import pytest
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability
from pythonfmu.variables import Boolean, Integer, Real

from fmu_runtime.safe_slave import SafeSlave


class Counter(SafeSlave):
    """y' = k u; counts its steps in an internal (unregistered) attribute."""

    direct_feedthrough: ClassVar[dict[str, tuple[str, ...]]] = {"echo": ("u",)}

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 1.0
        self.k = 2.0
        self.gain = 1.0
        self.y = 0.0
        self.echo = 0.0
        self.steps = 0
        self.level = 1
        self._count = 0
        io = {"variability": Fmi2Variability.continuous}
        out = {"causality": Fmi2Causality.output, "initial": Fmi2Initial.exact, **io}
        self.register(Real("u", causality=Fmi2Causality.input, description="in", **io), "N")
        self.register(Real("y", description="integral", **out), unit="m")
        self.register(Real("echo", description="u, directly", **out), unit="N")
        self.register(
            Integer(
                "steps",
                description="steps taken",
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.discrete,
                initial=Fmi2Initial.exact,
            )
        )
        self.register(
            Real(
                "k",
                description="gain",
                causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.fixed,
            ),
            unit="1",
        )
        self.register(
            Integer(
                "level",
                description="a fixed Integer parameter",
                causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.fixed,
            )
        )
        self.register(
            Real(
                "gain",
                description="tunable",
                causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.tunable,
            ),
            unit="1",
        )

    def _initialize(self):
        if self.k < 0:
            raise ValueError(f"k = {self.k}: expected >= 0")

    def _step(self, current_time, step_size):
        if self.u > 100.0:
            raise RuntimeError("u is too large for this toy")
        self.y += self.gain * self.k * self.u * step_size
        self.echo = self.u
        self._count += 1
        self.steps = self._count

    def _state_snapshot(self):
        return {"count": self._count}

    def _restore_snapshot(self, snapshot):
        self._count = snapshot["count"]


def _vr(slave: SafeSlave, name: str) -> int:
    return next(vr for vr, var in slave.vars.items() if var.name == name)


def _errors(slave: SafeSlave) -> str:
    return "\n".join(m.msg for m in slave.log_queue if m.status >= Fmi2Status.error)


def _initialise(counter: Counter, start_time: float = 0.0) -> Counter:
    counter.setup_experiment(start_time, None, None)
    counter.enter_initialization_mode()
    counter.exit_initialization_mode()
    return counter


@pytest.fixture
def slave() -> Counter:
    return _initialise(Counter(instance_name="toy"))


def test_step_before_initialisation_is_refused():
    counter = Counter(instance_name="toy")
    assert counter.do_step(0.0, 0.1) is False
    assert "not initialised" in _errors(counter)


def test_non_finite_input_is_refused_until_a_valid_value_is_written(slave):
    u = _vr(slave, "u")
    for bad in (math.nan, math.inf, -math.inf):
        slave.set_real([u], [bad])
        assert slave.u == 1.0
        assert slave.do_step(0.0, 0.1) is False
    assert "u = nan refused" in _errors(slave) and "u = inf refused" in _errors(slave)
    slave.set_real([u], [3.0])
    assert slave.do_step(0.0, 0.1) is True
    assert slave.y == pytest.approx(0.6)


def test_repeated_reads_and_writes_keep_every_rule(slave):
    # a host repeats the same lists every step: the cached fast path must refuse and
    # report exactly what the checked path does
    u, gain, y, echo = (_vr(slave, n) for n in ("u", "gain", "y", "echo"))
    for k in range(3):
        slave.set_real([u, gain], [2.0 + k, 0.5])
        assert slave.do_step(0.1 * k, 0.1) is True
        assert slave.get_real([y, echo]) == [pytest.approx(slave.y), 2.0 + k]
    assert slave.was_written("u") and slave.was_written("gain")
    slave.set_real([u, gain], [math.nan, 0.25])
    assert (slave.u, slave.gain) == (4.0, 0.25) and "u = nan refused" in _errors(slave)
    assert slave.do_step(0.3, 0.1) is False
    slave.set_real([u, gain], [1.0, 0.25])  # a good value clears the refusal
    assert slave.do_step(0.3, 0.1) is True
    slave.echo = math.inf
    assert slave.get_real([y, echo])[1] == math.inf
    assert "echo = inf is not finite" in _errors(slave)


def test_a_failing_setter_on_the_fast_path_is_reported_not_raised(slave):
    """The cached fast path of set_real calls the setters directly: an exception there is
    reported through the checked path, never raised into the host."""
    u = _vr(slave, "u")
    slave.set_real([u], [2.0])  # the list's plan is cached now
    slave.vars[u].setter = lambda value: 1 / 0
    slave.set_real([u], [3.0])
    assert "setReal of valueReference" in _errors(slave) and "ZeroDivisionError" in _errors(slave)
    slave.set_real([u], ["three"])  # not a number: refused, not raised
    assert "TypeError" in _errors(slave)


def test_fixed_parameter_is_refused_after_initialisation_tunable_is_not(slave):
    slave.set_real([_vr(slave, "k"), _vr(slave, "gain")], [5.0, 0.5])
    assert (slave.k, slave.gain) == (2.0, 0.5)
    assert "k = 5.0 refused: a fixed parameter" in _errors(slave)
    assert slave.do_step(0.0, 1.0) is True  # the refused write changed nothing
    assert slave.y == pytest.approx(1.0)
    slave.set_real([_vr(slave, "k")], [2.0])  # the value in use: accepted
    assert slave.do_step(1.0, 1.0) is True


def test_a_refused_set_integer_of_a_fixed_parameter_changes_nothing(slave):
    """A refused setInteger of a fixed parameter after initialisation made every later
    doStep return Discard."""
    slave.set_integer([_vr(slave, "level")], [2])
    assert slave.level == 1 and "level = 2 refused: a fixed parameter" in _errors(slave)
    assert [slave.do_step(0.1 * n, 0.1) for n in range(3)] == [True, True, True]


def test_outputs_unknown_references_and_wrong_types_are_refused(slave):
    slave.set_real([_vr(slave, "y")], [7.0])
    slave.set_integer([_vr(slave, "u")], [3])
    slave.set_real([999], [1.0])
    assert slave.y == 0.0 and slave.u == 1.0
    errors = _errors(slave)
    assert "y = 7.0 refused: an output cannot be set" in errors
    assert "u is a Real, not an Integer" in errors
    assert "no variable has valueReference 999" in errors
    assert slave.do_step(0.0, 0.1) is True  # refused calls changed nothing


def test_getters_never_raise(slave):
    assert slave.get_real([_vr(slave, "y"), 999, _vr(slave, "steps")]) == [0.0, 0.0, 0.0]
    assert slave.get_integer([_vr(slave, "steps")]) == [0]
    slave.vars[_vr(slave, "y")].getter = lambda: 1 / 0
    assert slave.get_real([_vr(slave, "y")]) == [0.0]
    slave.y = math.nan
    slave.vars[_vr(slave, "y")].getter = lambda: slave.y
    assert math.isnan(slave.get_real([_vr(slave, "y")])[0])
    errors = _errors(slave)
    assert "valueReference 999" in errors and "ZeroDivisionError" in errors
    assert "y = nan is not finite" in errors
    assert "steps' is an Integer, not a Real" in errors


def test_failing_step_is_discarded_and_leaves_the_state(slave):
    slave.set_real([_vr(slave, "u")], [1000.0])
    assert slave.do_step(0.0, 0.1) is False
    assert (slave.y, slave.steps) == (0.0, 0)
    assert "RuntimeError: u is too large for this toy" in _errors(slave)
    for bad_step in (0.0, -0.1, math.nan):
        assert slave.do_step(0.0, bad_step) is False
    assert "communication step nan s" in _errors(slave)


def test_failed_initialisation_is_reported_and_blocks_stepping():
    counter = Counter(instance_name="toy")
    counter.enter_initialization_mode()
    counter.set_real([_vr(counter, "k")], [-1.0])
    counter.exit_initialization_mode()
    assert counter.do_step(0.0, 0.1) is False
    assert "initialisation failed: k = -1.0: expected >= 0" in _errors(counter)


def test_state_round_trip_through_bytes_continues_identically(slave):
    u = _vr(slave, "u")
    slave.set_real([u], [0.3])
    for k in range(3):
        slave.do_step(0.1 * k, 0.1)
    blob = Counter._fmu_state_to_bytes(slave._get_fmu_state())
    slave.set_real([u], [0.7])
    slave.do_step(0.3, 0.1)
    first = (slave.y, slave.steps, slave._count)
    slave._set_fmu_state(Counter._fmu_state_from_bytes(blob))
    assert slave.u == 0.3
    slave.set_real([u], [0.7])
    slave.do_step(0.3, 0.1)
    assert (slave.y, slave.steps, slave._count) == first
    assert first[1] == 4


def test_bad_state_is_refused_until_a_good_one_is_restored(slave):
    good = slave._get_fmu_state()
    slave._set_fmu_state(Counter._fmu_state_from_bytes(b"not json"))
    assert slave.do_step(0.0, 0.1) is False
    assert "cannot deserialise the FMU state" in _errors(slave)
    slave._set_fmu_state({**good, "class": "AuvPlant"})
    assert "expected 'Counter'" in _errors(slave)
    slave._set_fmu_state(good)
    assert slave.do_step(0.0, 0.1) is True


def test_a_serialised_state_changed_cut_or_extended_is_refused(slave):
    """A host may keep serialised states (on disk, over a network): bytes that changed since
    are refused, not restored as a state nobody saved. A changed digit leaves valid JSON."""
    slave.set_real([_vr(slave, "u")], [0.3])
    slave.do_step(0.0, 0.1)
    blob = Counter._fmu_state_to_bytes(slave._get_fmu_state())
    assert Counter._fmu_state_from_bytes(blob)["base"]["time"] == 0.1
    for bad in (blob.replace(b'"time": 0.1', b'"time": 0.2'), blob[:-1], blob + b" "):
        decoded = Counter._fmu_state_from_bytes(bad)
        assert "CRC-32 differs" in decoded["error"], bad[-40:]
        slave._set_fmu_state(decoded)
        assert slave.do_step(0.1, 0.1) is False
    slave._set_fmu_state(Counter._fmu_state_from_bytes(blob))
    assert slave.do_step(0.1, 0.1) is True


def test_unserialisable_state_becomes_an_error_state():
    blob = SafeSlave._fmu_state_to_bytes({"x": math.nan})
    assert "error" in SafeSlave._fmu_state_from_bytes(blob)


def test_terminate_stops_stepping(slave):
    slave.terminate()
    assert slave.do_step(0.0, 0.1) is False
    assert "terminated" in _errors(slave)


def test_log_escapes_percent_for_printf_hosts(slave):
    slave.log("50% done")
    assert slave.log_queue[-1].msg == "50%% done"


def test_a_megabyte_message_reaches_the_host_shortened(slave):
    """A message naming a value the host wrote (megabytes of it) is cut to a length any
    host's logger can take, saying how much was left out."""
    slave.log("unknown vehicle '" + "x" * 1_000_000 + "'")
    logged = slave.log_queue[-1].msg
    assert len(logged) < 2300 and "characters left out" in logged and logged.endswith("x'")


def test_registration_requires_unit_description_and_variability():
    counter = Counter(instance_name="toy")
    with pytest.raises(ValueError, match="a unit is required"):
        counter.register(Real("z", causality=Fmi2Causality.input, description="z"))
    with pytest.raises(ValueError, match="a description is required"):
        counter.register(Real("z", causality=Fmi2Causality.input), unit="m")
    with pytest.raises(ValueError, match="need a variability"):
        counter.register(Integer("n", causality=Fmi2Causality.input, description="n"))


def test_description_has_units_and_declared_dependencies(monkeypatch):
    counter = Counter(instance_name="toy")
    root = counter.to_xml()
    units = {
        v.get("name"): v.find("Real").get("unit")
        for v in root.iter("ScalarVariable")
        if v.find("Real") is not None
    }
    assert units == {"u": "N", "y": "m", "echo": "N", "k": "1", "gain": "1"}
    dependencies = [u.get("dependencies") for u in root.iterfind("ModelStructure/Outputs/")]
    assert dependencies == ["", "1", ""]  # y, echo (on u = index 1), steps
    monkeypatch.setattr(Counter, "direct_feedthrough", {"y": ("k",)})
    with pytest.raises(ValueError, match="non-inputs"):
        counter.to_xml()


# --- FMI 2.0 call sequence, communication points, ranges ---------------------------


class Moded(Counter):
    """Counter with a bounded Integer and a bounded Real parameter."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.mode = 0
        self.rate = 1.0
        fixed = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        self.register(Integer("mode", description="0..2", **fixed), minimum=0, maximum=2)
        self.register(Real("rate", description="> 0", **fixed), unit="1/s", minimum=0.0)


def test_step_at_another_communication_point_is_refused_and_changes_nothing(slave):
    assert slave.do_step(0.0, 0.1) is True
    assert slave.do_step(0.0, 0.1) is False  # the FMU's time is 0.1 s now
    assert slave.do_step(0.25, 0.1) is False
    assert "currentCommunicationPoint = 0.25 s is not the FMU's current time 0.1 s" in _errors(
        slave
    )
    assert (slave.steps, slave.y) == (1, pytest.approx(0.2))
    assert slave.do_step(0.1, 0.1) is True  # the right point afterwards works
    assert slave.do_step(0.2, 0.1) is True  # the FMU is at 0.2 + 0.1 = 0.30000000000000004 s
    assert slave.do_step(0.3, 0.1) is True  # a master's t_3 = 0.3: rounding is accepted
    assert slave.steps == 4


def test_first_communication_point_is_the_start_time():
    counter = _initialise(Counter(instance_name="toy"), start_time=5.0)
    assert counter.do_step(0.0, 0.1) is False
    assert "not the FMU's current time 5.0 s" in _errors(counter)
    assert counter.do_step(5.0, 0.1) is True


def test_restored_state_restores_the_time(slave):
    slave.do_step(0.0, 0.1)
    state = slave._get_fmu_state()
    slave.do_step(0.1, 0.1)
    slave._set_fmu_state(state)
    assert slave.do_step(0.2, 0.1) is False
    assert slave.do_step(0.1, 0.1) is True


def test_initialisation_mode_is_entered_once_and_left_once():
    counter = Counter(instance_name="toy")
    counter.exit_initialization_mode()  # without enter: refused, nothing happens
    assert not counter.initialized
    counter.enter_initialization_mode()
    counter.enter_initialization_mode()  # twice: refused, still in initialisation mode
    counter.set_real([_vr(counter, "k")], [3.0])  # a fixed parameter: still writable
    counter.exit_initialization_mode()
    assert counter.initialized and counter.k == 3.0
    counter.exit_initialization_mode()  # again: refused, stays initialised
    counter.setup_experiment(1.0, None, None)  # too late: refused, the time stays 0
    errors = _errors(counter)
    assert "exitInitializationMode refused: the FMU is instantiated" in errors
    assert "enterInitializationMode refused: the FMU is in initialisation mode" in errors
    assert "exitInitializationMode refused: the FMU is initialised" in errors
    assert "setupExperiment refused: the FMU is initialised" in errors
    assert counter.do_step(0.0, 0.1) is True


def test_no_step_ends_past_a_stop_time_given_to_setup_experiment():
    """FMI 2.0 (fmi2SetupExperiment): with a stop time defined, a step computing past it is
    refused (a step ending on it, within rounding, is taken); a stop time before the start
    time, or not finite, is refused and leaves none defined."""
    counter = Counter(instance_name="toy")
    counter.setup_experiment(1.0, 0.5, None)
    counter.setup_experiment(0.0, math.nan, None)
    counter.setup_experiment(0.0, 0.3, None)
    counter.enter_initialization_mode()
    counter.exit_initialization_mode()
    assert [counter.do_step(0.1 * k, 0.1) for k in range(3)] == [True, True, True]
    assert counter.do_step(0.1 + 0.1 + 0.1, 0.1) is False
    assert counter.steps == 3
    errors = _errors(counter)
    assert "stopTime = 0.5 s, expected a finite number >= startTime (1.0 s)" in errors
    assert "stopTime = nan s" in errors
    assert "the step of 0.1 s ends past the stop time 0.3 s given to setupExperiment" in errors


def test_values_outside_the_declared_range_are_refused_and_declared():
    moded = Moded(instance_name="toy")
    moded.enter_initialization_mode()
    moded.set_integer([_vr(moded, "mode")], [7])
    moded.set_real([_vr(moded, "rate")], [-1.0])
    assert (moded.mode, moded.rate) == (0, 1.0)
    errors = _errors(moded)
    assert "mode = 7 refused: expected 0 <= mode <= 2" in errors
    assert "rate = -1.0 refused: expected 0.0 <= rate" in errors
    moded.set_integer([_vr(moded, "mode")], [2])  # a valid value clears the refusal
    moded.set_real([_vr(moded, "rate")], [0.5])
    moded.exit_initialization_mode()
    assert moded.initialized and moded.do_step(0.0, 0.1) is True
    declared = {
        v.get("name"): (v[0].get("min"), v[0].get("max"))
        for v in moded.to_xml().iter("ScalarVariable")
    }
    assert declared["mode"] == ("0", "2") and declared["rate"] == ("0.0", None)
    assert declared["k"] == (None, None)
    with pytest.raises(ValueError, match="only Real and Integer take a range"):
        moded.register(Boolean("b", description="b", causality=Fmi2Causality.input,
                               variability=Fmi2Variability.discrete), minimum=0)  # fmt: skip


def test_a_freed_instance_is_released_at_once_without_the_garbage_collector():
    """No reference cycle through the variables' getters and setters: pythonfmu's default
    ones close over the slave, which left every freed instance to the cyclic collector."""
    counter = _initialise(Counter(instance_name="toy"))
    counter.do_step(0.0, 0.1)
    gone = weakref.ref(counter)
    gc.disable()
    try:
        del counter
        assert gone() is None
    finally:
        gc.enable()


class Ramp(Counter):
    """A Counter that takes input derivatives and starts its output from a parameter."""

    interpolates_inputs = True

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.seen: list[tuple[float, float]] = []
        self.initialisations = 0

    def _initialize(self):
        super()._initialize()
        self.initialisations += 1
        self.y = 10.0 * self.k  # the output to start from depends on a parameter

    def _step(self, current_time, step_size):
        self.seen.append((self.input_derivative("u", 1), self.input_derivative("u", 2)))
        super()._step(current_time, step_size)


def test_input_derivatives_apply_to_the_next_step_only():
    ramp = _initialise(Ramp(instance_name="ramp"))
    u = _vr(ramp, "u")
    ramp.set_real_input_derivatives([u, u], [1, 2], [0.5, -2.0])
    assert ramp.do_step(0.0, 0.1) and ramp.do_step(0.1, 0.1)
    assert ramp.seen == [(0.5, -2.0), (0.0, 0.0)]  # cleared after the step they belong to
    assert _errors(ramp) == ""


@pytest.mark.parametrize(
    ("name", "order", "value", "reason"),
    [
        ("y", 1, 1.0, "valueReference 1 is not a Real input"),
        ("steps", 1, 1.0, "is not a Real input"),
        ("u", 3, 1.0, "expected order 1 or 2"),
        ("u", 1, math.nan, "expected order 1 or 2 and a finite number"),
    ],
)
def test_bad_input_derivatives_are_refused_and_none_is_taken(name, order, value, reason):
    ramp = _initialise(Ramp(instance_name="ramp"))
    u = _vr(ramp, "u")
    ramp.set_real_input_derivatives([u, _vr(ramp, name)], [1, order], [0.5, value])
    assert reason in _errors(ramp)
    ramp.do_step(0.0, 0.1)
    assert ramp.seen == [(0.0, 0.0)]  # the valid one in the refused call was not taken


def test_a_slave_that_does_not_interpolate_refuses_input_derivatives(slave):
    slave.set_real_input_derivatives([_vr(slave, "u")], [1], [0.5])
    assert "this FMU takes no input derivatives" in _errors(slave)
    assert slave.input_derivative("u", 1) == 0.0


def test_input_derivatives_are_kept_in_the_fmu_state_and_declared_in_the_description():
    ramp = _initialise(Ramp(instance_name="ramp"))
    u = _vr(ramp, "u")
    ramp.set_real_input_derivatives([u], [1], [0.25])
    saved = Ramp._fmu_state_from_bytes(Ramp._fmu_state_to_bytes(ramp._get_fmu_state()))
    ramp.do_step(0.0, 0.1)
    ramp._set_fmu_state(saved)
    ramp.do_step(0.0, 0.1)
    assert ramp.seen == [(0.25, 0.0), (0.25, 0.0)]
    cosimulation = ramp.to_xml().find("CoSimulation")
    assert cosimulation.get("canInterpolateInputs") == "true"
    assert cosimulation.get("maxOutputDerivativeOrder") == "0"
    plain = Counter(instance_name="toy").to_xml().find("CoSimulation")
    assert plain.get("canInterpolateInputs") == "false"


def test_an_output_read_in_initialisation_mode_is_the_value_the_fmu_starts_from():
    ramp = Ramp(instance_name="ramp")
    ramp.setup_experiment(0.0, None, None)
    ramp.enter_initialization_mode()
    ramp.set_real([_vr(ramp, "k")], [3.0])
    assert ramp.get_real([_vr(ramp, "y")]) == [30.0]
    ramp.set_real([_vr(ramp, "k")], [4.0])  # a later write is seen by the next read
    assert ramp.get_real([_vr(ramp, "y")]) == [40.0]
    assert ramp.get_real([_vr(ramp, "y")]) == [40.0]
    ramp.exit_initialization_mode()
    assert ramp.get_real([_vr(ramp, "y")]) == [40.0]
    assert ramp.initialisations == 2  # once per write read after, not again at exit
    assert _errors(ramp) == ""


def test_outputs_that_cannot_be_computed_yet_say_why_and_initialisation_fails():
    ramp = Ramp(instance_name="ramp")
    ramp.setup_experiment(0.0, None, None)
    ramp.enter_initialization_mode()
    ramp.set_real([_vr(ramp, "k")], [-1.0])
    ramp.get_real([_vr(ramp, "y")])
    assert "the outputs to start from cannot be computed yet: k = -1.0" in _errors(ramp)
    ramp.exit_initialization_mode()
    assert not ramp.initialized
    assert "initialisation failed: k = -1.0: expected >= 0" in _errors(ramp)


def test_a_step_whose_end_is_not_a_finite_time_after_its_start_is_refused():
    """From 1.7e308 s a step of 1e308 s would end at inf (and every later communication
    point would pass the check against an infinite time); from 1e17 s a step of 1 ms ends
    where it starts (a double cannot hold the difference). Both are refused, nothing
    changed; a step the time can hold is taken."""
    huge = _initialise(Counter(instance_name="toy"), start_time=1.7e308)
    assert huge.do_step(1.7e308, 1e308) is False
    assert huge.do_step(1.7e308, 1e300) is True  # ends at a finite time after it
    late = _initialise(Counter(instance_name="toy"), start_time=1e17)
    assert late.do_step(1e17, 1e-3) is False
    assert (late.steps, late._time) == (0, 1e17)
    assert late.do_step(1e17, 100.0) is True
    errors = _errors(huge) + _errors(late)
    assert "the step would end at t + h = inf s, not a finite time after t" in errors
    assert "the step would end at t + h = 1e+17 s, not a finite time after t" in errors


class Built(Counter):
    """A Counter whose ``_initialize`` builds what its steps use from a parameter and is
    not part of its snapshot (as the plant builds its model from its parameters)."""

    def _initialize(self):
        super()._initialize()
        self.rate = 10.0 * self.k

    def _step(self, current_time, step_size):
        super()._step(current_time, step_size)
        self.y += self.rate


def test_a_state_taken_in_initialisation_mode_starts_from_its_own_parameters():
    """A state taken in initialisation mode after a read (the outputs to start from
    computed with k = 3), set on an instance that had computed them with k = 5: the steps
    after exitInitializationMode use k = 3, as the instance that took it does, not what
    the other built from its own k before."""
    instances = []
    for k in (3.0, 5.0):
        built = Built(instance_name=f"k{k}")
        built.setup_experiment(0.0, None, None)
        built.enter_initialization_mode()
        built.set_real([_vr(built, "k")], [k])
        built.get_real([_vr(built, "y")])  # computes the outputs to start from
        instances.append(built)
    took, other = instances
    other._set_fmu_state(took._get_fmu_state())
    for built in instances:
        built.exit_initialization_mode()
        assert built.do_step(0.0, 0.1) is True
    assert other.y == took.y == pytest.approx(3.0 * 0.1 + 30.0)  # k u h + 10 k
    assert _errors(took) + _errors(other) == ""
