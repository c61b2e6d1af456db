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
from cosim.reproduction.earlier import keep_earlier, read_earlier
from cosim.reproduction.page import Evaluated, render
from cosim.reproduction.record import Figure, Section, effect_of, evaluate
from cosim.reproduction.runs import runner

PAGE = "reproduction.md"
FIGURES = "figures"


def _stderr(message: str) -> None:
    print(message, file=sys.stderr)


def reproduce(
    out: Path, values: Path, scenarios: bool = True, log: Callable[[str], None] = _stderr
) -> Path:
    """Write ``out/reproduction.md`` and its figures in ``out/figures`` (the figures the
    earlier page showed and this one does not are removed once it is written; other
    pages' figures there are left alone); return the page. Without ``scenarios``, the
    closed-loop rows, effects and figures are the earlier page's (:mod:`.earlier`).

    Args:
        out: the docs folder.
        values: the dissertation's printed values (``docs/dissertation-values.toml``).
        scenarios: run the closed-loop scenarios (minutes: each at two steps,
            :mod:`cosim.reproduction.runs`); without, their claims, effects and figures
            are kept from the earlier page, and read "not run" where it has none.
        log: receives one progress line per section.
    """
    refs = load_reference_values(values)
    sections = catalogue(refs)  # a printed value the file lacks: named before any work
    figures = out / FIGURES
    earlier = figures_of(out / PAGE)
    kept_from = read_earlier(out / PAGE)
    figures.mkdir(parents=True, exist_ok=True)
    evaluated, kept = [], 0
    with tempfile.TemporaryDirectory() as work:
        ctx = Context.create(refs, runner(Path(work), log) if scenarios else None)
        for section in sections:
            started = time.perf_counter()
            rows = tuple(evaluate(claim, ctx) for claim in section.claims)
            effects = tuple(effect_of(choice, ctx) for choice in section.choices)
            drawn = _figures(section, ctx, figures, earlier, log)
            part, kept_here, changed = keep_earlier(
                Evaluated(section, rows, drawn, effects), kept_from
            )
            evaluated.append(part)
            kept += kept_here
            for claim in changed:
                log(
                    f"kept {claim!r} with the earlier page's explanation, which its claim has "
                    "changed since: `auv-cosim reproduce` without --skip-scenarios updates it"
                )
            log(f"{section.title}: {time.perf_counter() - started:.1f} s")
    if kept:
        log(f"{kept} closed-loop rows and effects kept from the earlier page (not run)")
    page = out / PAGE
    page.write_text(render(evaluated, ctx), encoding="utf-8")
    for name in earlier - figures_of(page):  # the earlier page's figures this one drops
        (figures / name).unlink(missing_ok=True)
    return page


def figures_of(page: Path) -> set[str]:
    """The figures ``page`` shows (``![..](figures/NAME.png)``), none if it does not exist:
    the folder is shared with other pages' figures, which stay. An earlier page's figures
    are removed once the new page is written, so a reproduction that fails leaves the
    earlier page whole."""
    if not page.is_file():
        return set()
    return set(re.findall(rf"\]\({FIGURES}/([\w.-]+\.png)\)", page.read_text(encoding="utf-8")))


def _figures(
    section: Section, ctx: Context, folder: Path, earlier: set[str], log: Callable[[str], None]
) -> tuple[str, ...]:
    """The names of ``section``'s figures the page shows: those drawn now, and those not
    run (no closed-loop runs) that the earlier page showed and ``folder`` still holds."""
    shown = []
    for figure in section.figures:
        try:
            drawn = _draw(figure, ctx, folder, log)
        except NotRunError:
            drawn = figure.name in earlier and (folder / figure.name).is_file()
        if drawn:
            shown.append(figure.name)
    return tuple(shown)


def _draw(figure: Figure, ctx: Context, folder: Path, log: Callable[[str], None]) -> bool:
    """Draw ``figure`` into ``folder``; whether its file is there (a figure that cannot be
    drawn is left out of the page, and logged). Raises NotRunError for a figure of a run
    that was skipped."""
    path = folder / figure.name
    try:
        figure.draw(ctx, path)
    except NotRunError:
        raise
    except Exception as exc:  # the page goes on without it
        log(f"  {figure.name} not drawn: {type(exc).__name__}: {exc}")
        return False
    return path.is_file()
