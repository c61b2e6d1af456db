"""Test FMU for the master: x = t, built with pythonfmu's ``--only-one-per-process``
(canBeInstantiatedOnlyOncePerProcess="true"): a scenario may hold one instance of it.
Trivial on purpose: no exception can escape a callback."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class CosimTestSingleton(Fmi2Slave):
    description = "x = t, one instance per process (test FMU of the auv-cosim master)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.x = current_time + step_size
        return True
