"""Test FMU for the master: x = t, built with pythonfmu's ``--no-variable-step``
(canHandleVariableCommunicationStepSize="false"): the master must not shorten its last step.
Trivial on purpose: no exception can escape a callback."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class CosimTestFixedStep(Fmi2Slave):
    description = "x = t, fixed communication step (test FMU of the auv-cosim master)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.x = current_time + step_size
        return True
