"""Test FMU for the master: direct feedthrough of every numeric type, y = u + bias, n_out =
n_in, b_out = b_in, declared in ModelStructure (pythonfmu declares no dependencies, so
``to_xml`` adds them): what initialisation, the Gauss-Seidel order and the algebraic-loop
check read. Trivial on purpose: no exception can escape a callback."""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class CosimTestFeedthrough(Fmi2Slave):
    description = "y = u + bias, n_out = n_in, b_out = b_in (test FMU of the auv-cosim master)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.bias = 0.0
        self.n_in = 0
        self.n_out = 0
        self.b_in = False
        self.b_out = False
        continuous = {"variability": Fmi2Variability.continuous}
        discrete = {"variability": Fmi2Variability.discrete}
        self.register_variable(Real("u", causality=Fmi2Causality.input, **continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=self._y))
        self.register_variable(
            Real("bias", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
        )
        self.register_variable(Integer("n_in", causality=Fmi2Causality.input, **discrete))
        self.register_variable(
            Integer("n_out", causality=Fmi2Causality.output, getter=self._n, **discrete)
        )
        self.register_variable(Boolean("b_in", causality=Fmi2Causality.input, **discrete))
        self.register_variable(
            Boolean("b_out", causality=Fmi2Causality.output, getter=self._b, **discrete)
        )

    def _y(self):
        return self.u + self.bias

    def _n(self):
        return self.n_in

    def _b(self):
        return self.b_in

    def do_step(self, current_time, step_size):
        return True

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        index = {v.get("name"): str(i + 1) for i, v in enumerate(root.find("ModelVariables"))}
        for unknown in root.iterfind("ModelStructure/Outputs/Unknown"):
            name = next(n for n, i in index.items() if i == unknown.get("index"))
            source = {"y": "u", "n_out": "n_in", "b_out": "b_in"}[name]
            unknown.set("dependencies", index[source])
        return root
