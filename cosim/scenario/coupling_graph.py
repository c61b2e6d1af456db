"""What the connections imply: the Gauss-Seidel order, and the algebraic loops they close.

An output *feeds through* from an input when the FMU's ``ModelStructure`` lists that input
among the output's dependencies (FMI 2.0, section 2.2.8): its value at a communication
point depends on the input's value at that same point. An output whose ``<Unknown>``
declares no ``dependencies`` attribute is taken here as feeding through from nothing.
FMI 2.0 would assume every input, but pythonfmu writes no dependencies at all, and
every feedback loop through such an FMU would then count as algebraic.

* :func:`algebraic_loop`: a cycle of connections and feedthroughs (``a.y -> b.u -> b.y ->
  a.u -> a.y``): no order can give every instance its inputs' values at the same point,
  so the scenario is refused with the loop named.
* :func:`connection_order`: the Gauss-Seidel order the connections imply: every source
  before the instances it drives, so no consumer steps on a value one step old. Within a
  feedback loop (plant and controller), the instances that feed nothing through from the
  loop come first, in the order of the file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any


def feedthrough(model_description: Any) -> dict[str, set[str]]:
    """Output name -> the names of the inputs it depends on directly (declared only)."""
    result: dict[str, set[str]] = {}
    for unknown in model_description.outputs:
        if unknown.variable is None or not unknown.dependencies:
            continue
        inputs = {v.name for v in unknown.dependencies if v.causality == "input"}
        if inputs:
            result[unknown.variable.name] = inputs
    return result


def algebraic_loop(
    passes: Mapping[str, Mapping[str, set[str]]], connections: Sequence[tuple[str, str]]
) -> list[str] | None:
    """The first loop of connections (source, target ``"<instance>.<variable>"``) and
    feedthroughs (``passes``: instance -> output -> inputs), as the variables it passes
    through, the first repeated at the end; None if there is none."""
    edges: dict[str, list[str]] = {}
    for source, target in connections:
        edges.setdefault(source, []).append(target)
    for instance, outputs in passes.items():
        for output, inputs in outputs.items():
            for name in sorted(inputs):
                edges.setdefault(f"{instance}.{name}", []).append(f"{instance}.{output}")
    done: set[str] = set()
    for start in edges:
        loop = _cycle_from(start, edges, done)
        if loop is not None:
            return loop
    return None


def _cycle_from(start: str, edges: Mapping[str, list[str]], done: set[str]) -> list[str] | None:
    """A cycle reachable from ``start`` (iterative depth-first search), or None."""
    path: list[str] = []
    on_path: set[str] = set()
    stack: list[tuple[str, int]] = [(start, 0)]
    while stack:
        node, i = stack.pop()
        if i == 0:
            if node in on_path:
                return [*path[path.index(node) :], node]
            if node in done:
                continue
            path.append(node)
            on_path.add(node)
        following = edges.get(node, [])
        if i < len(following):
            stack.append((node, i + 1))
            stack.append((following[i], 0))
        else:
            done.add(node)
            on_path.discard(node)
            path.pop()
    return None


def connection_order(
    names: Sequence[str],
    passes: Mapping[str, Mapping[str, set[str]]],
    connections: Sequence[tuple[str, str]],
) -> tuple[str, ...]:
    """The instances ``names`` (file order) in the Gauss-Seidel order the connections
    (source, target) imply; see the module docstring."""
    drives: dict[str, set[str]] = {name: set() for name in names}  # instance -> consumers
    feeds: dict[str, set[str]] = {name: set() for name in names}  # instance -> its sources
    through: dict[str, set[str]] = {name: set() for name in names}  # inputs fed through
    for instance, outputs in passes.items():
        for inputs in outputs.values():
            through[instance] |= inputs
    driven_inputs: dict[str, dict[str, str]] = {name: {} for name in names}
    for source, target in connections:
        src, tgt = source.split(".", 1)[0], target.split(".", 1)[0]
        if src != tgt:
            drives[src].add(tgt)
            feeds[tgt].add(src)
            driven_inputs[tgt][target.split(".", 1)[1]] = src
    order: list[str] = []
    left = list(names)
    while left:
        ready = [n for n in left if not (feeds[n] & set(left))]
        if not ready:  # a feedback loop: first those that need no same-point value from it
            ready = [
                n for n in left if not any(driven_inputs[n].get(i) in left for i in through[n])
            ] or left
        order.append(ready[0])
        left.remove(ready[0])
    return tuple(order)
