"""The study's index page ``index.html``: what ran, how it went, the figures inline.

Laid out like ``auv-cosim report``'s page: a summary table (scenario, factors, runs
complete and failed), links to ``runs.csv`` and ``runs.parquet``, each figure linked
full size, the metrics not plotted in one compact sentence (constant, missing or too many;
the final values counted, their names in folded lists below it), and the failed runs with
their errors, a list under a heading of its own (no colour says it). The summary table
has a caption and row headers (``scope="row"``) for a screen reader.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from cosim.paths import path_text
from cosim.study.plots import PANELS_MAX
from cosim.study.statistics import SENSITIVITY_NAME, STATISTICS_NAME
from cosim.whole_file import write_whole

INDEX_PAGE = "index.html"
FAILED_SHOWN = 50  # failed runs listed on the page (all are in runs.csv)


def write_index(
    out_dir: Path,
    facts: Mapping[str, Any],
    rows: Sequence[Mapping[str, Any]],
    figures: Mapping[str, Path],
    not_plotted: Sequence[str],
    alts: Mapping[str, str] | None = None,
    monte_carlo: bool = False,
) -> Path:
    """Write ``out_dir/index.html``; ``facts`` are label -> value lines of the summary,
    ``alts`` each figure's alt text by its title (:func:`cosim.study.plots.figure_alts`;
    the title without one); ``monte_carlo``: link the statistics and sensitivity tables
    (:mod:`cosim.study.statistics`) too."""
    summary = "\n".join(
        f'<tr><th scope="row">{_escape(label)}</th><td>{_escape(value)}</td></tr>'
        for label, value in facts.items()
    )
    images = "\n".join(
        f'<h2>{_escape(title)}</h2>\n<p><a href="{_escape(_rel(path, out_dir))}">'
        f'<img src="{_escape(_rel(path, out_dir))}" alt="{_escape((alts or {}).get(title, title))}"'
        ' style="max-width:100%">'
        "</a></p>"
        for title, path in figures.items()
    )
    quiet = _not_plotted(not_plotted, rows)
    failed = [row for row in rows if row["status"] != "complete"]
    failures = ""
    if failed:
        items = "\n".join(
            f"<li><code>{_escape(row['run'])}</code>: {_escape(row['error'])}</li>"
            for row in failed[:FAILED_SHOWN]
        )
        more = (
            f"<p>... and {len(failed) - FAILED_SHOWN} more in runs.csv</p>"
            if len(failed) > FAILED_SHOWN
            else ""
        )
        failures = f"<h2>Failed runs</h2>\n<ul>\n{items}\n</ul>\n{more}"
    name = path_text(out_dir.resolve().name)  # a name's bytes that are no UTF-8 escaped
    page = f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>auv-cosim study {_escape(name)}</title>
<style>body {{ font-family: sans-serif; max-width: 1400px; margin: 2em auto; }}
th {{ text-align: left; padding-right: 2em; }}
h1, code {{ overflow-wrap: anywhere; }}</style></head>
<body>
<h1>Study {_escape(name)}</h1>
<p>Results: <a href="runs.csv">runs.csv</a>, <a href="runs.parquet">runs.parquet</a>
(one row per run){MONTE_CARLO_LINKS if monte_carlo else ""}</p>
<table>
<caption>Study summary</caption>
{summary}
</table>
{quiet}
{images}
{failures}
</body>
</html>
"""
    path = out_dir / INDEX_PAGE  # undecoded text elsewhere (a run's error) escaped
    write_whole(path, lambda tmp: tmp.write_text(page, encoding="utf-8", errors="backslashreplace"))
    return path


MONTE_CARLO_LINKS = (
    f';\n<a href="{STATISTICS_NAME}">{STATISTICS_NAME}</a> (each metric\'s mean, standard '
    f'deviation and percentiles over the runs) and <a href="{SENSITIVITY_NAME}">'
    f"{SENSITIVITY_NAME}</a> (Spearman's rank correlation of each factor with each metric, "
    "the strongest first)"
)


FOLDED = (  # name prefix, what the folded list is called
    ("final.", "final values (final.&lt;instance&gt;.&lt;variable&gt;)"),
    ("coupling_error.final.", "coupling errors of final values (coupling_error.final.&lt;...&gt;)"),
)


def _not_plotted(names: Sequence[str], rows: Sequence[Mapping[str, Any]] = ()) -> str:
    """One sentence: the metrics not plotted by name, each that some of the ``rows`` lack
    with how many gave it (a settling time most runs never reached is a finding, not a
    constant), the final values and their coupling errors (``check_step``) counted; then
    their names in folded lists, after the sentence's paragraph (a ``<details>`` inside a
    ``<p>`` ends it: a browser broke the sentence there)."""
    if not names:
        return ""
    folded = {prefix: [n for n in names if n.startswith(prefix)] for prefix, _ in FOLDED}
    hidden = {n for group in folded.values() for n in group}
    listed = [f"<code>{_escape(n)}</code>{_given(n, rows)}" for n in names if n not in hidden]
    lists = []
    for prefix, what in FOLDED:
        if folded[prefix]:
            listed.append(f"{len(folded[prefix])} {what}")
            shown = ", ".join(_escape(n) for n in folded[prefix])
            lists.append(f"\n<details><summary>The {what}</summary>{shown}</details>")
    return (
        f"<p>Not plotted: {', '.join(listed)}. (Fewer than two distinct values among the "
        f"runs that gave it, beyond the {PANELS_MAX} that vary most, or not a key figure or "
        "manoeuvre metric; "
        "<code>[metrics] collect</code> chooses; every value is in runs.csv.)</p>" + "".join(lists)
    )


def _given(name: str, rows: Sequence[Mapping[str, Any]]) -> str:
    """ " (given by k of n runs)" when some of ``rows`` lack ``name`` (a failed run, a
    figure never reached), else ""."""
    given = sum(row.get(name) is not None for row in rows)
    return f" (given by {given} of {len(rows)} runs)" if given < len(rows) else ""


def _escape(value: Any) -> str:
    return html.escape(str(value))


def _rel(path: Path, out_dir: Path) -> str:
    return path.relative_to(out_dir).as_posix()
