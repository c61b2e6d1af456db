"""How long a third-party FMU with many aliased outputs takes to load, stage by stage, as
a ratio to fmpy's own reading of its model description in the same process (the baseline:
no loader of ours can read less than fmpy does).

The FMU is the master tests' integrator (``tests/fmus/cosim_test_integrator.py``) with
``--aliases`` more names of its output ``x``, all one value reference, as a Modelica tool
exports aliases. Each size is measured on fresh copies (the interface cache is by file)::

    python scripts/bench_aliases.py                    # 10^4 and 10^5 aliases
    python scripts/bench_aliases.py --aliases 1000 100000 --repeats 3

A stage of ours that grew faster than the description would show as a ratio growing with
the size; a linear one keeps its ratio. The load average is printed beside the figures.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import tempfile
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

from cosim.engine import slave
from cosim.fmus.build import pythonfmu_build
from cosim.fmus.interface import check_archive, read_interface
from cosim.scenario.spec import scenario_from_toml

INTEGRATOR = Path(__file__).resolve().parents[1] / "tests" / "fmus" / "cosim_test_integrator.py"
_OUTPUT_X = re.compile(r'<ScalarVariable\s+name="x".*?</ScalarVariable>', re.DOTALL)


def aliased(fmu: Path, dest: Path, aliases: int) -> Path:
    """``fmu`` copied to ``dest`` with ``aliases`` more names (``x_alias<i>``) of its
    output ``x``."""
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as out:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                declared = _OUTPUT_X.search(text)
                if declared is None:
                    raise SystemExit(f"{fmu}: no output x in its model description")
                copies = "".join(
                    declared[0].replace('name="x"', f'name="x_alias{i}"', 1) for i in range(aliases)
                )
                data = text.replace("</ModelVariables>", copies + "</ModelVariables>", 1).encode()
            out.writestr(item, data)
    return dest


def _seconds(call: Callable[[], object]) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def stages(fmu: Path, folder: Path) -> dict[str, float]:
    """Seconds of each stage of loading ``fmu`` (a fresh copy each, so that no cache of
    an earlier stage answers): fmpy's reading (the baseline), our archive check, our whole
    interface reading (fmpy's included), a scenario of it loaded, and the check that an
    extraction is the FMU loaded."""
    from fmpy import extract, read_model_description

    copies = [shutil.copyfile(fmu, folder / f"{i}-{fmu.name}") for i in range(2)]
    unzipped = Path(extract(str(fmu), unzipdir=str(folder / "unzipped")))
    scenario = f'stop_time = 0.1\n[coupling]\nstep = 0.1\n[instances.f]\nfmu = "{copies[1].name}"\n'
    return {
        "fmpy read_model_description": _seconds(lambda: read_model_description(str(fmu))),
        "check_archive": _seconds(lambda: check_archive(copies[0])),
        "read_interface": _seconds(lambda: read_interface(copies[0])),
        "scenario loaded": _seconds(lambda: scenario_from_toml(scenario, base_dir=folder)),
        "extracted_guid": _seconds(lambda: slave.extracted_guid(unzipped)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--aliases", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--repeats", type=int, default=1, help="rounds of every size")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-aliases-") as temporary:
        folder = Path(temporary)
        base = pythonfmu_build(INTEGRATOR, folder, "CosimTestIntegrator", "--handle-state")
        print(f"load average before: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        for round_ in range(args.repeats):
            for n in args.aliases:
                work = folder / f"r{round_}-{n}"
                work.mkdir()
                fmu = aliased(base, work / "Aliased.fmu", n)
                times = stages(fmu, work)
                baseline = times["fmpy read_model_description"]
                for stage, seconds in times.items():
                    print(
                        f"{n:>8} aliases  {stage:<28} {seconds:7.2f} s  {seconds / baseline:5.2f}"
                    )
        print(f"load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
