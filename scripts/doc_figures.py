"""The figures README.md and docs/*.md quote from the built-in scenarios, from the runs.

    python scripts/doc_figures.py [--write]

A figure in a page is a number written right after a marker naming the scenario and the
metric it comes from, ``<!-- zigzag-20:overshoot_1_deg -->0.87``: the marker is invisible
once rendered. The metric is a key figure (``yaw_settling_time_s``, ...:
:mod:`cosim.metrics.key_figures`) or a manoeuvre metric (``tactical_diameter_m``, ...:
:mod:`cosim.metrics.manoeuvres`) of the scenario's ``summary.json``; a marker without one,
``<!-- bs-3 -->3.21``, is the yaw settling time (s). A metric may name a figure inside one,
its keys and list positions (counted from 1) joined by dots: ``survey:legs.7.completed_at_s``
(summary.json's ``legs``, the seventh). The number keeps as many decimals as the page gives
it (and a leading ``+``).

Each scenario a marker names runs once, as shipped (``auv-cosim run <id> --no-rrd``, into
a temporary folder). Without ``--write`` the figures that differ from the pages are
listed (exit 1 if any); with it the pages are rewritten. A marker naming a scenario or a
metric no run has is refused in one line (exit 2).
``tests/cosim/test_builtin_scenarios.py`` checks every marked figure against the same runs.
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosim.errors import CosimError
from cosim.runner import run_scenario

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_METRIC = "yaw_settling_time_s"
MARKER = re.compile(
    r"<!-- (?P<scenario>[a-z0-9][\w.-]*)(?::(?P<metric>\w+(?:\.\w+)*))? -->"
    r"(?P<value>[+-]?\d+(?:\.\d+)?)"
)


@dataclass(frozen=True)
class Figure:
    """One marked number of a page."""

    page: Path
    scenario: str
    metric: str
    text: str  # the number as the page writes it


def pages(root: Path = ROOT) -> list[Path]:
    """README.md and every Markdown page of docs/."""
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


def figures_in(page: Path) -> list[Figure]:
    """The marked figures of ``page``, in page order."""
    text = page.read_text(encoding="utf-8")
    return [
        Figure(page, m["scenario"], m["metric"] or DEFAULT_METRIC, m["value"])
        for m in MARKER.finditer(text)
    ]


def metric_value(
    scenario: str, metric: str, key_figures: Mapping[str, Any], manoeuvre: Mapping[str, Any]
) -> float:
    """``metric`` of a run of ``scenario`` (its key figures and manoeuvre metrics, as in
    summary.json). Raises ValueError naming the metric if the run does not have it or it
    is null (a settling time never reached)."""
    value = key_figures.get(metric, _inside(manoeuvre, metric.split(".")))
    if isinstance(value, bool) or not isinstance(value, int | float):
        known = sorted([*key_figures, *(k for k in manoeuvre if k != "manoeuvre")])
        raise ValueError(
            f"{scenario}: metric {metric!r} is {value!r} in its run: expected a number, one "
            f"of {', '.join(known)}"
        )
    return float(value)


def _inside(figures: Any, path: Sequence[str]) -> Any:
    """The figure at ``path`` (keys, and list positions counted from 1) in ``figures``;
    None where there is none."""
    for key in path:
        if isinstance(figures, Mapping):
            figures = figures.get(key)
        elif isinstance(figures, list) and key.isdigit() and 1 <= int(key) <= len(figures):
            figures = figures[int(key) - 1]
        else:
            return None
    return figures


def shown(value: float, like: str) -> str:
    """``value`` with as many decimals as ``like`` has, and its leading ``+`` if it has
    one (and the value is not negative)."""
    decimals = len(like.split(".")[1]) if "." in like else 0
    text = f"{value:.{decimals}f}"
    if text.startswith("-") and float(text) == 0.0:
        text = text[1:]  # no "-0.0"
    return "+" + text if like.startswith("+") and not text.startswith("-") else text


def rewrite(text: str, values: Mapping[tuple[str, str], float]) -> str:
    """``text`` with every marked figure replaced by ``values[(scenario, metric)]``."""

    def replace(m: re.Match[str]) -> str:
        metric = m["metric"] or DEFAULT_METRIC
        number = shown(values[(m["scenario"], metric)], m["value"])
        return m[0][: m.start("value") - m.start()] + number

    return MARKER.sub(replace, text)


def differences(
    figures: Iterable[Figure], values: Mapping[tuple[str, str], float]
) -> list[tuple[Figure, str]]:
    """The figures whose number differs from ``values[(scenario, metric)]`` as the page
    would write it, each with that number."""
    now = [(f, shown(values[(f.scenario, f.metric)], f.text)) for f in figures]
    return [(figure, new) for figure, new in now if new != figure.text]


def run_values(figures: Iterable[Figure], out: Path) -> dict[tuple[str, str], float]:
    """Each marked (scenario, metric), from one run of each scenario as shipped."""
    wanted: dict[str, set[str]] = {}
    for figure in figures:
        wanted.setdefault(figure.scenario, set()).add(figure.metric)
    values = {}
    for scenario, metrics in wanted.items():
        outcome = run_scenario(scenario, out / scenario, no_rrd=True)
        if not outcome.result.complete:
            raise RuntimeError(f"{scenario}: {outcome.result.error}")
        for metric in metrics:
            values[(scenario, metric)] = metric_value(
                scenario, metric, outcome.figures, outcome.manoeuvre or {}
            )
        print(f"  {scenario}: run", file=sys.stderr)
    return values


def main(argv: Sequence[str] | None = None, root: Path = ROOT) -> int:
    """The command; ``root``: the repository whose pages are read."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="rewrite the pages")
    args = parser.parse_args(argv)
    marked = [figure for page in pages(root) for figure in figures_in(page)]
    try:
        with tempfile.TemporaryDirectory(prefix="doc-figures-") as out:
            values = run_values(marked, Path(out))
    except (CosimError, ValueError, RuntimeError) as exc:  # a marker naming what no run has
        print(f"doc_figures.py: {exc}", file=sys.stderr)
        return 2
    stale = differences(marked, values)
    for figure, new in stale:
        where = figure.page.relative_to(root)
        print(f"{where}: {figure.scenario} {figure.metric}: {figure.text} -> {new}")
    if args.write:
        written = {figure.page for figure in marked}
        for page in written:
            page.write_text(rewrite(page.read_text(encoding="utf-8"), values), encoding="utf-8")
        print(f"{len(marked)} figures in {len(written)} pages written")
        return 0
    print(f"{len(marked)} figures, {len(stale)} differ from the runs")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
