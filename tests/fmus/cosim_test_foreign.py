"""Test FMU for the master: what FMUs of other groups do and ours do not. Parameters of
every type set from start values (``gain`` Integer, ``invert`` Boolean, ``label`` String,
``level`` Integer (a test rewrites it to an Enumeration), ``k`` a tunable Real) drive the
output y = (-1 if invert else 1) * (k * gain * t + level + len(label)); ``echo`` repeats
``label``'s length after every step. ``bad_at`` (> 0) makes y NaN from that time (``inf``
with ``bad_inf``); ``chatter`` lines are logged at every step (warnings with
``chatter_warns``, else OK), ``warn_at`` logs a warning once past that time; an OK line
``constructed`` is logged while it is instantiated (before any fmi2SetDebugLogging);
``discard_at`` returns False from doStep with a warning logged (pythonfmu reports
fmi2Discard); ``shout`` (a String, if not empty) is logged as a warning at every step, as
written (pythonfmu's binary passes it to the host as a printf format, its ``%`` as they
are); ``state_fails`` makes fmi2GetFMUstate answer an exception (pythonfmu:
fmi2Fatal, its reason logged over two lines). Trivial on purpose: no exception escapes a
callback but the one asked for."""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status


class CosimTestForeign(Fmi2Slave):
    description = "an FMU with the habits of other tools' FMUs (auv-cosim tests)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.t = 0.0
        self.gain, self.invert, self.label, self.level, self.k = 1, False, "ab", 0, 1.0
        self.bad_at, self.bad_inf, self.chatter, self.chatter_warns = -1.0, False, 0, False
        self.warn_at, self.discard_at, self.state_fails = -1.0, -1.0, False
        self.shout = ""
        fixed = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        tunable = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.tunable}
        self.register_variable(Integer("gain", **tunable))
        self.register_variable(Boolean("invert", **tunable))
        self.register_variable(String("label", **tunable))
        self.register_variable(Integer("level", **fixed))
        self.register_variable(Real("k", **tunable))
        self.register_variable(Real("bad_at", **tunable))
        self.register_variable(Boolean("bad_inf", **fixed))
        self.register_variable(Integer("chatter", **fixed))
        self.register_variable(Boolean("chatter_warns", **fixed))
        self.register_variable(Real("warn_at", **fixed))
        self.register_variable(Real("discard_at", **fixed))
        self.register_variable(Boolean("state_fails", **fixed))
        self.register_variable(String("shout", **fixed))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=self._y))
        self.register_variable(
            Integer(
                "echo",
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.discrete,
                getter=self._echo,
            )
        )
        self.log("constructed", Fmi2Status.ok)

    def _y(self):
        if 0.0 < self.bad_at <= self.t + 1e-12:
            return float("inf") if self.bad_inf else float("nan")
        sign = -1.0 if self.invert else 1.0
        return sign * (self.k * self.gain * self.t + self.level + len(self.label))

    def _echo(self):
        return len(self.label)

    def do_step(self, current_time, step_size):
        for i in range(self.chatter):
            status = Fmi2Status.warning if self.chatter_warns else Fmi2Status.ok
            self.log(f"step at {current_time:.3f}: line {i}", status)
        if self.shout:
            self.log(self.shout, Fmi2Status.warning)
        if 0.0 < self.warn_at <= current_time + 1e-12:
            self.log(f"warned at {current_time:.3f}", Fmi2Status.warning)
            self.warn_at = -1.0
        if 0.0 < self.discard_at <= current_time + 1e-12:
            self.log("step too large, try a shorter one", Fmi2Status.warning)
            return False
        self.t = current_time + step_size
        return True

    def _get_fmu_state(self):
        if self.state_fails:
            raise RuntimeError("this FMU cannot save its state")
        return super()._get_fmu_state()
