"""Test FMU for the master: a clock with outputs of every type: x = x0 + t (Real), count
(Integer: steps taken), odd (Boolean: count is odd), label (String: "<prefix> <count>",
prefix a String input, "step" to start with) and label_length (Integer: its length). At
t >= ``stop_at`` (> 0) its doStep ends the simulation: it returns False without logging an
error, which pythonfmu reports as fmi2Discard with fmi2Terminated true and the last
successful time (FMI 2.0, section 4.2.3). Trivial on purpose: no exception can escape a
callback."""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String


class CosimTestSource(Fmi2Slave):
    description = "a clock with Real, Integer, Boolean and String outputs (auv-cosim tests)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.0
        self.x0 = 2.0
        self.count = 0
        self.odd = False
        self.label = "step 0"
        self.prefix = "step"
        self.stop_at = -1.0
        discrete = {"causality": Fmi2Causality.output, "variability": Fmi2Variability.discrete}
        tunable = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.tunable}
        self.register_variable(Real("x", causality=Fmi2Causality.output))
        self.register_variable(Integer("count", **discrete))
        self.register_variable(Boolean("odd", **discrete))
        self.register_variable(String("label", **discrete))
        self.register_variable(Integer("label_length", getter=self._length, **discrete))
        self.register_variable(
            String("prefix", causality=Fmi2Causality.input, variability=Fmi2Variability.discrete)
        )
        self.register_variable(Real("x0", **tunable))
        self.register_variable(Real("stop_at", **tunable))

    def exit_initialization_mode(self):
        self.x = self.x0

    def do_step(self, current_time, step_size):
        if 0.0 < self.stop_at <= current_time + 1e-12:
            return False  # ends the simulation (no error logged)
        self.x = self.x0 + current_time + step_size
        self.count += 1
        self.odd = self.count % 2 == 1
        self.label = f"{self.prefix} {self.count}"
        return True

    def _length(self):
        return len(self.label)
