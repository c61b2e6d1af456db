"""Run exported systems in a third-party FMI master and write the traces as CSV.

Run in a subprocess by ``tests/cosim/export/test_interop.py``, one system per process::

    python tests/interop_runner.py JOB.json

A third-party master may crash its host process, and a pythonfmu FMU cannot be loaded
twice in one process from different folders: the second load reuses the Python modules
of the first (``sys.modules``), whose extraction folder the first execution has already
deleted.

``JOB.json`` is ``{"tool": "libcosim" | "ecos" | "fmpy-container", "source": PATH,
"step": h, "n_steps": N, "out": CSV, "variables": ["plant.yaw", ...]}`` (with
``"parallel": true|false`` for fmpy-container). The runner loads ``source`` (an SSP
archive, or for libcosim also a folder holding OspSystemStructure.xml, the only source of
fmpy-container), steps it ``N`` times and writes ``time`` and the variables after every
step (rows for t = h ... N h). libcosim takes the step from the file (its annotation or
BaseStepSize) and the runner checks it; ecos is given ``step`` and the SSP parameter set
``initial``; fmpy-container packs the OSP system into one FMU with
``fmpy.fmucontainer.create_fmu_container``, as docs/hosts.md does, and runs it with
``fmpy.simulate_fmu`` at ``step``.
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


def run_fmpy_container(job: dict) -> list[list[float]]:
    """The recipe of docs/hosts.md ("fmpy: several FMUs in one"): every OSP simulator a
    component, its initial values start values of container parameters (or inputs), every
    connection a container connection, every output a container output."""
    import xml.etree.ElementTree as ET

    from fmpy import read_model_description, simulate_fmu
    from fmpy.fmucontainer import (
        Component,
        Configuration,
        Connection,
        Variable,
        create_fmu_container,
    )

    ns = {"o": "http://opensimulationplatform.com/MSMI/OSPSystemStructure"}
    folder = Path(job["source"])
    system = ET.parse(folder / "OspSystemStructure.xml").getroot()
    configuration = Configuration(fmiVersion="2.0", parallelDoStep=job["parallel"])
    outputs, units = [], {}
    for simulator in system.iterfind(".//o:Simulator", ns):
        name, fmu = simulator.get("name"), folder / simulator.get("source")
        description = read_model_description(fmu)
        variables = {v.name: v for v in description.modelVariables}
        units.update({unit.name: unit for unit in description.unitDefinitions})
        configuration.components.append(Component(filename=fmu, name=name))
        for initial in simulator.iterfind(".//o:InitialValue", ns):
            v, value = variables[initial.get("variable")], initial[0]
            configuration.variables.append(
                Variable(
                    type=value.tag.split("}")[1],
                    variability=v.variability,
                    causality=v.causality,
                    name=f"{name}.{v.name}",
                    start=value.get("value"),
                    unit=v.unit,
                    mapping=[(name, v.name)],
                )
            )
        outputs += [(name, v) for v in variables.values() if v.causality == "output"]
    for name, v in outputs:
        configuration.variables.append(
            Variable(
                type=v.type,
                variability=v.variability,
                causality="output",
                name=f"{name}.{v.name}",
                unit=v.unit,
                mapping=[(name, v.name)],
            )
        )
    configuration.unitDefinitions = list(units.values())  # rad with its display unit deg
    for connection in system.iterfind(".//o:VariableConnection", ns):
        start, end = connection.iterfind("o:Variable", ns)
        configuration.connections.append(
            Connection(
                start.get("simulator"), start.get("name"), end.get("simulator"), end.get("name")
            )
        )
    container = Path(job["out"]).with_suffix(".fmu")
    create_fmu_container(configuration, container)
    result = simulate_fmu(
        container,
        stop_time=job["n_steps"] * job["step"],
        output_interval=job["step"],
        output=job["variables"],
    )
    if len(result) != job["n_steps"] + 1:
        raise RuntimeError(f"fmpy ran {len(result) - 1} steps, expected {job['n_steps']}")
    return [[float(row[name]) for name in ("time", *job["variables"])] for row in result[1:]]


def main(job_file: str) -> int:
    job = json.loads(Path(job_file).read_text())
    tool = job["tool"]
    try:
        if tool == "fmpy-container":
            import fmpy.fmucontainer  # noqa: F401
        elif tool == "libcosim":
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
    runners = {"libcosim": run_libcosim, "ecos": run_ecos, "fmpy-container": run_fmpy_container}
    rows = runners[tool](job)
    with open(job["out"], "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["time", *job["variables"]])
        writer.writerows([repr(x) for x in row] for row in rows)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
