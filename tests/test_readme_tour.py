"""The README's quick tour names files that exist: every scenario or study file an
``auv-cosim run`` or ``auv-cosim sweep`` of its tour reads is in the repository and loads."""

from __future__ import annotations

import re

from repo_paths import ROOT

from cosim.study.spec import load_study

TOUR = re.compile(r"## A quick tour\n(.*?)\n## ", re.DOTALL)
READ = re.compile(r"auv-cosim (run|sweep) (\S+\.toml)")


def test_every_file_the_readme_quick_tour_reads_exists_and_loads() -> None:
    tour = TOUR.search((ROOT / "README.md").read_text(encoding="utf-8"))
    assert tour is not None, "README.md has no '## A quick tour' section"
    named = READ.findall(tour.group(1))
    assert any(command == "sweep" for command, _ in named), "the tour runs no study file"
    for command, name in named:
        assert (ROOT / name).is_file(), f"the quick tour's `auv-cosim {command} {name}`: no file"
        if command == "sweep":
            load_study(ROOT / name)
