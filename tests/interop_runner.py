"""Run exported systems in a third-party FMI master and write the traces as CSV.

Run in a subprocess by ``tests/cosim/export/test_interop.py``, one system per process::

    python tests/interop_runner.py JOB.json

A third-party master may crash its host process, and a pythonfmu FMU cannot be loaded
twice in one process from different folders: the second load reuses the Python modules
of the first (``sys.modules``), whose extraction folder the first execution has already
deleted.

``JOB.json`` is ``{"tool": "libcosim" | "ecos", "source": PATH, "step": h, "n_steps": N,
"out": CSV, "variables": ["plant.yaw", ...]}``. The runner loads ``source`` (an SSP
archive, or for libcosim also a folder holding OspSystemStructure.xml), steps it ``N``
times and writes ``time`` and the variables after every step (rows for t = h ... N h).
libcosim takes the step from the file (its annotation or BaseStepSize) and the runner
checks it; ecos is given ``step`` and the SSP parameter set ``initial``.
Exit code 77 means the tool is installed but a system library it needs is missing (the
message says which); a missing pip package is an ordinary failure.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

UNAVAILABLE = 77


def run_libcosim(job: dict) -> list[list[float]]:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    source = job["source"]
    if source.endswith(".ssp"):
        execution = CosimExecution.from_ssp_file(source)
    else:
        execution = CosimExecution.from_osp_config_file(source)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    references = []
    for name in job["variables"]:
        instance, variable = name.split(".", 1)
        index = execution.slave_index_from_instance_name(instance)
        refs = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
        references.append((index, refs[variable]))
    rows = []
    for n in range(1, job["n_steps"] + 1):
        if not execution.step():
            raise RuntimeError(f"libcosim: step {n} failed: {execution.status()}")
        t_ns = execution.status().current_time
        expected_ns = round(n * job["step"] * 1e9)
        if t_ns != expected_ns:
            raise RuntimeError(f"libcosim stepped to {t_ns} ns, expected {expected_ns} ns")
        rows.append([t_ns * 1e-9] + [observer.last_real_values(i, [r])[0] for i, r in references])
    return rows


def run_ecos(job: dict) -> list[list[float]]:
    from ecospy import EcosLib, EcosSimulation

    EcosLib.set_log_level("warn")
    identifiers = [name.replace(".", "::", 1) for name in job["variables"]]
    rows = []
    with EcosSimulation(ssp_path=job["source"], step_size=job["step"]) as simulation:
        if not simulation.init(parameter_set="initial"):
            raise RuntimeError(f"ecos: initialisation failed: {EcosLib.get_last_error()}")
        for _ in range(job["n_steps"]):
            t = simulation.step()
            rows.append([t] + [simulation.get_real(i) for i in identifiers])
        simulation.terminate()
    return rows


def main(job_file: str) -> int:
    job = json.loads(Path(job_file).read_text())
    tool = job["tool"]
    try:
        if tool == "libcosim":
            import libcosimpy.CosimExecution  # noqa: F401
        else:
            from cosim.export.ecos_support import preload_tbb

            preload_tbb()  # libtbb.so.12 from the pip package tbb, where installed
            import ecospy  # noqa: F401
    except ImportError as exc:  # a pip package of the test extra: install it, no skip
        print(f"{tool}: {exc}; install the test extra: pip install '.[test]'", file=sys.stderr)
        return 1
    except OSError as exc:  # a library it needs (ecos: TBB, from pip or apt) is missing
        print(f"{tool} cannot be loaded here: {exc}", file=sys.stderr)
        return UNAVAILABLE
    rows = run_libcosim(job) if tool == "libcosim" else run_ecos(job)
    with open(job["out"], "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["time", *job["variables"]])
        writer.writerows([repr(x) for x in row] for row in rows)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
