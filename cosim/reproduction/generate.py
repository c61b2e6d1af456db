"""``auv-cosim reproduce``: evaluate every claim in one loop, draw the figures, write
``docs/reproduction.md``."""

from __future__ import annotations

import re
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from cosim.analysis.reference_values import load_reference_values
from cosim.reproduction.catalogue import catalogue
from cosim.reproduction.context import Context, NotRunError
from cosim.reproduction.page import Evaluated, render
from cosim.reproduction.record import Figure, effect_of, evaluate
from cosim.reproduction.runs import runner

PAGE = "reproduction.md"
FIGURES = "figures"


def _stderr(message: str) -> None:
    print(message, file=sys.stderr)


def reproduce(
    out: Path, values: Path, scenarios: bool = True, log: Callable[[str], None] = _stderr
) -> Path:
    """Write ``out/reproduction.md`` and its figures in ``out/figures`` (the figures the
    earlier page showed are removed first; other pages' figures there are left alone);
    return the page.

    Args:
        out: the docs folder.
        values: the dissertation's printed values (``docs/dissertation-values.toml``).
        scenarios: run the closed-loop scenarios (minutes: each at two steps,
            :mod:`cosim.reproduction.runs`); without, their claims read "not run".
        log: receives one progress line per section.
    """
    refs = load_reference_values(values)
    figures = out / FIGURES
    figures.mkdir(parents=True, exist_ok=True)
    remove_figures_of(out / PAGE)
    evaluated = []
    with tempfile.TemporaryDirectory() as work:
        ctx = Context.create(refs, runner(Path(work), log) if scenarios else None)
        for section in catalogue(refs):
            started = time.perf_counter()
            rows = tuple(evaluate(claim, ctx) for claim in section.claims)
            effects = tuple(effect_of(choice, ctx) for choice in section.choices)
            drawn = tuple(f.name for f in section.figures if _draw(f, ctx, figures, log))
            evaluated.append(Evaluated(section, rows, drawn, effects))
            log(f"{section.title}: {time.perf_counter() - started:.1f} s")
    page = out / PAGE
    page.write_text(render(evaluated, ctx), encoding="utf-8")
    return page


def remove_figures_of(page: Path) -> None:
    """Remove the figures ``page`` shows (``![..](figures/NAME.png)``), if it exists: the
    folder is shared with other pages' figures, which stay."""
    if not page.is_file():
        return
    for name in re.findall(rf"\]\({FIGURES}/([\w.-]+\.png)\)", page.read_text(encoding="utf-8")):
        (page.parent / FIGURES / name).unlink(missing_ok=True)


def _draw(figure: Figure, ctx: Context, folder: Path, log: Callable[[str], None]) -> bool:
    """Draw ``figure`` into ``folder``; whether its file is there (a figure that cannot be
    drawn is left out of the page, and logged)."""
    path = folder / figure.name
    try:
        figure.draw(ctx, path)
    except NotRunError:
        return False
    except Exception as exc:  # the page goes on without it
        log(f"  {figure.name} not drawn: {type(exc).__name__}: {exc}")
        return False
    return path.is_file()
