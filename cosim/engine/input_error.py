"""An adaptive step's error from its extrapolated inputs (``error_estimate = "extrapolation"``).

Schierz, Arnold & Clauss, "Co-simulation with communication step size control", J. Appl.
Math. Comput. 38 (2012) 115-130: over a communication step [t, t + H] an instance
follows its inputs as the polynomial the master extrapolated from the values they had at
its last points (:mod:`cosim.engine.extrapolation`; a constant where it holds them); at
the end of the step its sources' outputs say what the inputs really were. The difference
of the two at t + H::

    du_i = |u_i + H u_i' + H^2 / 2 u_i'' - y_src(i)(t + H)|

is the extrapolation's error, O(H^(q + 1)) for a polynomial of degree q, the leading term
of what the step got wrong. It costs nothing beyond the step itself: one doStep per
instance and step, a state save per step and a restore only when the step is rejected
(step doubling takes three doSteps per step).

When the value at t + H is known: under Jacobi, and under Gauss-Seidel for an input whose
source comes after its instance in the order (or is the instance itself), it is the
source's output at the end of the step (``now``). An input whose source steps before its
instance (vert-1's plant taking the autopilot's commands: the command for t + H is
computed when the autopilot steps from t + H) is known only in the next step, after its
source has stepped (``later``): that error, of the step just accepted, predicts the next
step's as du (H_next / H)^(q + 1) and counts in the next step's judgement (the accepted
step is not redone). Left out: inputs with a fault on their connection (what they are
given is not what their source says), Integer and Boolean inputs, the inputs of an
instance whose step (a step multiple k > 1) does not end with the master's, and every
input across an event, override or fault boundary (the extrapolation restarts there).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cosim.engine.slave import Slave
from cosim.engine.timeline import Timeline


@dataclass(frozen=True)
class _Used:
    """The polynomial one instance followed over its step from grid point ``n``."""

    n: int
    span: int  # grid points
    u: np.ndarray
    first: np.ndarray  # 1 / s
    second: np.ndarray  # 1 / s^2
    epoch: int

    def at(self, s: float) -> np.ndarray:
        """Its value s seconds after its point."""
        return self.u + s * self.first + (0.5 * s * s) * self.second


class InputError:
    """The extrapolation error of every receiving instance's Real inputs (module
    docstring): :meth:`took` after an instance took its inputs, :meth:`errors` at the end
    of a step."""

    def __init__(
        self,
        order: list[Slave],
        index: Mapping[str, int],
        jacobi: bool,
        timeline: Timeline | None,
        grid: float,
    ) -> None:
        names, position = list(index), {s.name: i for i, s in enumerate(order)}
        self.grid, self.timeline = grid, timeline
        self.now: dict[str, np.ndarray] = {}  # per instance: inputs known at the step's end
        self.later: dict[str, np.ndarray] = {}  # ... known once their source stepped again
        for slave in order:
            if not slave.n_inputs:
                continue
            source = [names[i].split(".", 1)[0] for i in slave.input_sources]
            known = np.array([jacobi or position[s] >= position[slave.name] for s in source])
            kept = np.ones(slave.n_inputs, dtype=bool)
            for slot, _ in timeline.on_inputs.get(slave.name, ()) if timeline else ():
                kept[slot] = False
            self.now[slave.name], self.later[slave.name] = known & kept, ~known & kept
        self.used: dict[str, _Used] = {}
        self.lagged: dict[str, tuple[np.ndarray, int]] = {}  # du of the last step, its span

    def took(self, slave: Slave, n: int, span: int) -> None:
        """``slave`` took its inputs at point n for a step of ``span`` grid points: the
        error of its last step's ``later`` inputs is known now; its polynomial is kept."""
        if slave.name not in self.now:
            return
        epoch = self.timeline.epoch_of(slave.name, n) if self.timeline is not None else 0
        last, later = self.used.get(slave.name), self.later[slave.name]
        self.lagged.pop(slave.name, None)
        if last is not None and last.n + last.span == n and last.epoch == epoch and later.any():
            du = np.abs(last.at(last.span * self.grid) - slave.inputs)[later]
            self.lagged[slave.name] = (du, last.span)
        rates = slave.input_rates
        sent = rates.derivatives(n * self.grid) if rates is not None else None
        zero = np.zeros(slave.n_inputs)
        first, second = sent if sent is not None else (zero, zero)
        self.used[slave.name] = _Used(n, span, slave.inputs.copy(), first, second, epoch)

    def errors(
        self, order: list[Slave], z: np.ndarray, end: int, k: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """(z index of the source, |du|) of every input judged at the end of the step
        ending at grid point ``end``: the ``now`` inputs' errors, and the ``later``
        inputs' errors of the last step scaled to this one's span by (ratio)^k."""
        sources, errors = [], []
        for slave in order:
            used = self.used.get(slave.name)
            if used is None or used.n + used.span != end:
                continue
            now = self.now[slave.name]
            if now.any():
                actual = z[slave.input_sources[now]]
                errors.append(np.abs(used.at(used.span * self.grid)[now] - actual))
                sources.append(slave.input_sources[now])
            if slave.name in self.lagged:
                du, span = self.lagged[slave.name]
                errors.append(du * (used.span / span) ** k)
                sources.append(slave.input_sources[self.later[slave.name]])
        if not errors:
            return np.zeros(0, dtype=np.intp), np.zeros(0)
        return np.concatenate(sources), np.concatenate(errors)

    def snapshot(self) -> tuple[Any, ...]:
        return dict(self.used), dict(self.lagged)

    def restore(self, saved: tuple[Any, ...]) -> None:
        self.used, self.lagged = dict(saved[0]), dict(saved[1])
