"""Test FMU for the master: a sampled gain u = -k x, computed from the input at the start of
each step (and at initialisation) and held over the step."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class CosimTestGain(Fmi2Slave):
    description = "u = -k x, sampled (test FMU of the auv-cosim master)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.0
        self.u = 0.0
        self.k = 2.0
        self.register_variable(Real("x", causality=Fmi2Causality.input, description="state"))
        self.register_variable(
            Real(
                "u",
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.discrete,
                description="command",
            )
        )
        self.register_variable(
            Real(
                "k",
                causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.tunable,
                description="gain",
            )
        )

    def exit_initialization_mode(self):
        self.u = -self.k * self.x

    def do_step(self, current_time, step_size):
        self.u = -self.k * self.x
        return True
