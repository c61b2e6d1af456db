"""The FMI floor: a pythonfmu FMU whose step costs nothing, in the interface shape of one
of our FMUs (its Real inputs and outputs). The one definition of both sides:
scripts/bench_floor.py writes each side's script from this file, the class named after
the side (``BenchTrivialPlant``, ``BenchTrivialController``) and the shape its own.

A script per side, whole, rather than a side importing this module: pythonfmu 0.7's own
binary re-executes the script at every instantiation and takes a reference away from its
module's namespace each time (fmu_runtime/entry.py), which a module defining no function
of its own does not survive past a few instances."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Real

N_INPUTS, N_OUTPUTS = 8, 20  # Real inputs, Real outputs: the side's (here the plant's)


class BenchTrivial(Fmi2Slave):
    description = (
        f"{N_INPUTS} inputs -> {N_OUTPUTS} outputs, y_i = u_(i mod n_inputs) (benchmark floor)"
    )

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
