"""``auv-cosim export``: load a scenario, write it in one format, say where and what to mind."""

from __future__ import annotations

import shlex
from pathlib import Path

from cosim.errors import CosimError
from cosim.export.osp import export_osp
from cosim.export.ssp import export_ssp
from cosim.scenario.spec import load_scenario


def export_scenario(
    scenario: str | Path,
    *,
    ssp: Path | None,
    osp: Path | None,
    fmu_dir: Path,
    force: bool = False,
) -> int:
    """Export the built-in scenario id or scenario file ``scenario`` as an SSP archive at
    ``ssp`` or an OSP system structure in the folder ``osp`` (exactly one); 0 on success.

    ``fmu_dir`` is where the built-in FMUs live (built there on first use). An existing
    ``ssp`` file is replaced only if an earlier export wrote it, or with ``force``.

    Raises:
        CosimError: both or neither of ``ssp`` and ``osp`` given, or the export failed.
    """
    if (ssp is None) == (osp is None):
        raise CosimError("give exactly one of --ssp FILE or --osp DIR")
    resolved = load_scenario(scenario, fmu_dir=fmu_dir)
    if ssp is not None:
        print(f"SSP archive: {export_ssp(resolved, ssp, overwrite=force)}")
    elif osp is not None:
        print(f"OSP system structure: {export_osp(resolved, osp)}")
    coupling = resolved.coupling
    if coupling.algorithm != "jacobi" or coupling.extrapolation != "none":
        print(
            f"note: libcosim and ecos couple Jacobi-style with held inputs; {resolved.id} "
            f"runs {coupling.algorithm} with {_inputs(coupling.extrapolation)} in "
            f"auv-cosim, so compare with "
            f"`auv-cosim run {shlex.quote(str(scenario))} --algorithm jacobi "
            "--extrapolation none`"
        )
    sources = {c.source_instance for c in resolved.connections}
    slow = {n: k for n, k in coupling.step_multiples.items() if k > 1 and n in sources}
    if slow:
        print(
            f"note: {', '.join(f'{n} steps every {k} h' for n, k in slow.items())}: libcosim "
            "hands a slow instance's outputs on when its step ends, auv-cosim and ecos from "
            "the next base step: results differ (docs/hosts.md)"
        )
    return 0


def _inputs(extrapolation: str) -> str:
    """The extrapolation in words: ``held inputs``, ``quadratic extrapolation``."""
    return "held inputs" if extrapolation == "none" else f"{extrapolation} extrapolation"
