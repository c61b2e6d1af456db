"""Test FMU for the master, built with pythonfmu's ``--only-one-per-process``
(canBeInstantiatedOnlyOncePerProcess="true"), as FMUs whose code keeps global state
declare: its Integer output ``live`` is the number of its instances alive in the process,
which such an FMU needs to stay 1. Trivial on purpose: no exception can escape a callback."""

import weakref

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer

_ALIVE = weakref.WeakSet()  # the global state: every instance of this class in the process


class CosimTestSingleton(Fmi2Slave):
    description = "its instances alive in the process (test FMU of the auv-cosim master)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        _ALIVE.add(self)
        self.live = len(_ALIVE)
        self.register_variable(
            Integer("live", causality=Fmi2Causality.output, variability=Fmi2Variability.discrete)
        )

    def do_step(self, current_time, step_size):
        self.live = len(_ALIVE)
        return True
