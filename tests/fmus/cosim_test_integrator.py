"""Test FMU for the master: x' = u, integrated exactly over a step with u held.

Fault injection for the master's tests: at t >= ``fail_at`` doStep logs an error and fails;
a step longer than ``longest_step`` (s, negative = any) is refused the same way, unstarted;
at t >= ``nan_at`` the output x becomes NaN (negative = never); a non-empty ``started_file``
is created at the first step (so a test knows the loop runs). Trivial on purpose: no
exception can escape a callback (pythonfmu would crash the host).
"""

import contextlib
from pathlib import Path

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Status


class CosimTestIntegrator(Fmi2Slave):
    description = "x' = u (test FMU of the auv-cosim master)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.x = 0.0
        self.x0 = 1.0
        self.fail_at = -1.0
        self.nan_at = -1.0
        self.longest_step = -1.0
        self.started_file = ""
        self.register_variable(Real("u", causality=Fmi2Causality.input, description="rate"))
        self.register_variable(Real("x", causality=Fmi2Causality.output, description="state"))
        for name in ("x0", "fail_at", "nan_at", "longest_step"):
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.parameter,
                    variability=Fmi2Variability.tunable,
                    description=name,
                )
            )
        self.register_variable(
            String(
                "started_file",
                causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.fixed,
                description="touched at the first step",
            )
        )

    def exit_initialization_mode(self):
        self.x = self.x0

    def do_step(self, current_time, step_size):
        if 0.0 <= self.fail_at <= current_time:
            self.log(f"injected failure at t = {current_time:.3f}", Fmi2Status.error)
            return False
        if 0.0 <= self.longest_step < step_size:
            self.log(f"step {step_size:.4f} s refused: longer than longest_step", Fmi2Status.error)
            return False
        if self.started_file:
            with contextlib.suppress(OSError):
                Path(self.started_file).touch()
            self.started_file = ""
        self.x = self.x + step_size * self.u
        if 0.0 <= self.nan_at <= current_time + step_size:
            self.x = float("nan")
        return True
