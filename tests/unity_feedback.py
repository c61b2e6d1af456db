"""The poles of a python-control loop closed by unity negative feedback, for the tests.

Closed by hand, not by ``control.feedback(opened, 1.0)``: python-control 0.10.2 makes the
constant 1 a static StateSpace by setting its arrays' shape, which NumPy 2.5 deprecates
(a DeprecationWarning; under ``-W error`` ``feedback`` falls back to an
InterconnectedSystem without ``.poles``). The tests then read our loops, not that path.
"""

import control
import numpy as np


def unity_feedback_poles(opened: control.StateSpace) -> np.ndarray:
    """The closed-loop poles (z for a sampled loop, 1/s for a continuous one) of the
    strictly proper SISO loop ``opened`` fed back negatively through 1: the eigenvalues
    of A - B C (with no feedthrough, u = r - y = r - C x)."""
    assert opened.ninputs == opened.noutputs == 1, "a SISO loop"
    assert not np.any(opened.D), "strictly proper: unity negative feedback is A - B C"
    return np.linalg.eigvals(opened.A - opened.B @ opened.C)
