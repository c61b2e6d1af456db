"""The FMI floor's controller side: a pythonfmu FMU with the autopilot's interface shape (20 Real
inputs, 8 Real outputs) whose step costs nothing (scripts/bench_cosim.py builds it)."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Real

N_INPUTS, N_OUTPUTS = 20, 8


class BenchTrivialController(Fmi2Slave):
    description = "20 inputs -> 8 outputs, y_i = u_(i mod n_inputs) (benchmark floor)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = [0.0] * N_INPUTS
        self.y = [0.0] * N_OUTPUTS
        for i in range(N_INPUTS):
            self.register_variable(
                Real(f"u{i}", causality=Fmi2Causality.input, description="input",
                     getter=lambda i=i: self.u[i], setter=lambda v, i=i: self.u.__setitem__(i, v))
            )  # fmt: skip
        for i in range(N_OUTPUTS):
            self.register_variable(
                Real(f"y{i}", causality=Fmi2Causality.output, description="output",
                     getter=lambda i=i: self.y[i])
            )  # fmt: skip

    def do_step(self, current_time, step_size):
        self.y = [self.u[i % N_INPUTS] for i in range(N_OUTPUTS)]
        return True
