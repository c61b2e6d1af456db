"""bs-3 in host Pythons that are not the build's: which numpy and numba releases run our FMUs.

Builds the FMUs and exports bs-3 as an OSP system structure into ``--work``, makes one
virtual environment per row of :data:`HOSTS` there (this machine's base CPython, pip from
the package index: minutes the first time, reused after), and in each runs the plant and
the autopilot with fmpy, Jacobi-coupled with held inputs at the export's step, for
``--stop`` seconds, in a clean environment (PATH and a HOME of its own only). Each row is
compared with the same run in this Python with numba (the build's) and with
``AUV_COSIM_NO_JIT=1`` (its numpy path): "bit-identical", or the largest difference of
any Real output at any step relative to max(1, |value|). The FMU's warnings are printed
under the row.

``--python PY`` (repeatable) makes the environments from the CPython ``PY`` instead (another
minor version: pyenv's ``/root/.pyenv/versions/3.13.0/bin/python``), with the newest numpy,
without and with numba, and also steps the plant alone for ``--stop`` seconds in a C host
(``tests/fmu_runtime/hosts/stepper.c``, compiled with ``cc``) in an empty environment with
``AUV_FMU_PYTHON`` naming the environment, compared with the same C host given the build's
Python.

Usage: python scripts/host_pythons.py [--work /tmp/host-pythons] [--stop 10] [--python PY]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

# name: what pip installs beside fmpy, then what it installs with --no-deps (a numba that
# does not support the numpy beside it), and files removed from site-packages after
HOSTS: dict[str, tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]] = {
    "numpy 1.23.2": (("numpy==1.23.2",), (), ()),
    "numpy 1.23.5, numba 0.58.1": (("numpy==1.23.5", "numba==0.58.1"), (), ()),
    "numpy 1.26.4": (("numpy==1.26.4",), (), ()),
    "numpy 1.26.4, numba 0.59.1": (("numpy==1.26.4", "numba==0.59.1"), (), ()),
    "numpy 2.0.0": (("numpy==2.0.0",), (), ()),
    "numpy 2.0.0, numba 0.60.0": (("numpy==2.0.0", "numba==0.60.0"), (), ()),
    "newest numpy": (("numpy",), (), ()),
    "newest numpy and numba": (("numpy", "numba"), (), ()),
    "numpy 2.0.0, numba 0.58.1 (needs numpy < 1.27)": (
        ("numpy==2.0.0",),
        ("numba==0.58.1", "llvmlite==0.41.1"),
        (),
    ),
    "numpy 2.0.0, numba 0.60.0 without libllvmlite.so": (
        ("numpy==2.0.0", "numba==0.60.0"),
        (),
        ("llvmlite/binding/libllvmlite.so",),
    ),
}
# the rows made from another CPython (--python): what pip offers for it today
NEWEST = ("newest numpy", "newest numpy and numba")
STEPPER = Path(__file__).resolve().parent.parent / "tests" / "fmu_runtime" / "hosts" / "stepper.c"

# Run in each host Python with fmpy and numpy only: prints one JSON line.
RUNNER = """
import json, os, shutil, sys, tempfile
import xml.etree.ElementTree as ET
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

folder, stop = sys.argv[1], float(sys.argv[2])
ns = {"o": "http://opensimulationplatform.com/MSMI/OSPSystemStructure"}
root = ET.parse(os.path.join(folder, "OspSystemStructure.xml")).getroot()
h = float(root.find("o:BaseStepSize", ns).text)
setters = {"Real": ("setReal", float), "Integer": ("setInteger", int),
           "Boolean": ("setBoolean", lambda x: x in ("true", "1")), "String": ("setString", str)}
slaves, work = {}, tempfile.mkdtemp()
for node in root.find("o:Simulators", ns):
    name, fmu = node.get("name"), os.path.join(folder, node.get("source"))
    md = read_model_description(fmu)
    refs = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu, os.path.join(work, name)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    for start in node.find("o:InitialValues", ns):
        (value,) = list(start)
        setter, kind = setters[value.tag.split("}")[1]]
        getattr(slave, setter)([refs[start.get("variable")]], [kind(value.get("value"))])
    slave.exitInitializationMode()
    outputs = [v.valueReference for v in md.modelVariables
               if v.causality == "output" and v.type == "Real"]
    slaves[name] = (slave, refs, outputs)
links = [[(v.get("simulator"), v.get("name")) for v in c.findall("o:Variable", ns)]
         for c in root.find("o:Connections", ns)]
rows = []
for k in range(round(stop / h)):
    held = [slaves[a][0].getReal([slaves[a][1][x]])[0] for (a, x), _ in links]
    for ((_, _), (b, y)), value in zip(links, held):
        slaves[b][0].setReal([slaves[b][1][y]], [value])
    for slave, _, _ in slaves.values():
        slave.doStep(currentCommunicationPoint=k * h, communicationStepSize=h)
    rows.append([v.hex() for n in sorted(slaves) for v in slaves[n][0].getReal(slaves[n][2])])
for slave, _, _ in slaves.values():
    slave.terminate()
    slave.freeInstance()
shutil.rmtree(work)
print(json.dumps(rows))
"""


def host_python(work: Path, name: str, base: str) -> Path:
    """The virtual environment of row ``name`` of :data:`HOSTS` made from the CPython
    ``base`` (once): its python."""
    packages, without_deps, removed = HOSTS[name]
    tag = "" if base == sys._base_executable else f"{_version(base)}-"  # type: ignore[attr-defined]
    folder = work / "venvs" / "".join(c if c.isalnum() else "-" for c in tag + name)
    python = folder / "bin" / "python"
    if not (folder / "done").exists():
        shutil.rmtree(folder, ignore_errors=True)
        subprocess.run([base, "-m", "venv", folder], check=True)
        pip: list[str | Path] = [python, "-m", "pip", "install", "-q"]
        subprocess.run([*pip, "fmpy", *packages], check=True)
        if without_deps:
            subprocess.run([*pip, "--no-deps", *without_deps], check=True)
        for site in folder.glob("lib/python*/site-packages"):
            for path in removed:
                (site / path).unlink()
        (folder / "done").touch()
    return python


def _version(python: Path | str) -> str:
    """``python``'s version, "3.13.0"."""
    ask = "import platform; print(platform.python_version())"
    return subprocess.run(
        [python, "-c", ask], capture_output=True, text=True, check=True
    ).stdout.strip()


def stepper(work: Path, stop: float) -> tuple[Path, list[str]]:
    """The C host, compiled once into ``work``, and its arguments after the library: the
    plant's extraction under ``work``, ``stop`` s in steps of 10 ms, constant actuator
    inputs, every Real output."""
    host, plant = work / "stepper", work / "plant"
    if not host.exists():
        subprocess.run(["cc", "-O1", "-o", host, STEPPER, "-ldl"], check=True)
    shutil.rmtree(plant, ignore_errors=True)
    with zipfile.ZipFile(work / "fmus" / "AuvPlant.fmu") as archive:
        archive.extractall(plant)
    root = ET.parse(plant / "modelDescription.xml").getroot()
    refs = {v.get("name"): v.get("valueReference") for v in root.iter("ScalarVariable")}
    outputs = [v.get("valueReference", "") for v in root.iter("ScalarVariable")
               if v.get("causality") == "output" and v.find("Real") is not None]  # fmt: skip
    inputs = f"{refs['tunnel_force']}=0.5,{refs['mass_position_cmd']}=0.02"
    steps = str(round(stop / 0.01))
    return host, [(plant / "resources").as_uri(), root.get("guid", ""), steps, "0.01", inputs,
                  ",".join(outputs)]  # fmt: skip


def c_host_run(
    work: Path, python: Path | str, stop: float, **extra: str
) -> tuple[list[str], list[str]]:
    """The rows the C host prints with ``AUV_FMU_PYTHON=python`` (and ``extra`` in its
    environment), and its log lines."""
    host, arguments = stepper(work, stop)
    library = work / "plant" / "binaries" / "linux64" / "AuvPlant.so"
    env = {"PATH": "/usr/bin:/bin", "HOME": str(work / "home"), "AUV_FMU_PYTHON": str(python),
           **extra}  # fmt: skip
    done = subprocess.run([host, library, *arguments], capture_output=True, text=True, env=env,
                          check=False)  # fmt: skip
    lines = done.stdout.splitlines()
    rows = [line for line in lines if line[:1].isdigit()]
    if done.returncode != 0 or lines[-1:] != ["exit 0"]:
        return [], lines[-3:]
    return rows, [line for line in lines if line.startswith("LOG")]


def installed(python: Path) -> str:
    """The numpy and numba releases pip installed for ``python`` (numba's, imported or not)."""
    ask = "from importlib.metadata import version as v; print(v('numpy'), end=' ')\n"
    ask += "try: print('numba', v('numba'))\nexcept Exception: print('no numba')"
    done = subprocess.run([python, "-c", ask], capture_output=True, text=True, check=True)
    return f"numpy {done.stdout.strip()}"


def run(python: Path | str, work: Path, stop: float, **extra: str) -> tuple[list, list[str]]:
    """The rows of hex floats one host Python steps, and the lines it said besides."""
    env = {"PATH": "/usr/bin:/bin", "HOME": str(work / "home"), **extra}
    done = subprocess.run(
        [python, work / "runner.py", work / "bs-3-osp", str(stop)],
        capture_output=True, text=True, env=env, check=False,
    )  # fmt: skip
    lines = (done.stdout + done.stderr).strip().splitlines()
    if done.returncode != 0 or not lines:
        return [], lines[-3:]
    return json.loads(lines[-1]), [line for line in lines[:-1] if "WARNING" in line]


def apart(reference: list, rows: list) -> str:
    """ "bit-identical", or the largest relative difference of ``rows`` from ``reference``."""
    if not rows:
        return "did not run"
    if rows == reference:
        return "bit-identical"
    worst = max(
        abs(float.fromhex(a) - float.fromhex(b)) / max(1.0, abs(float.fromhex(a)))
        for x, y in zip(reference, rows, strict=True)
        for a, b in zip(x, y, strict=True)
    )
    return f"{worst:.1e}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--work", type=Path, default=Path("/tmp/host-pythons"))
    parser.add_argument("--stop", type=float, default=10.0)
    parser.add_argument("--python", action="append", default=[], metavar="PY",
                        help="a CPython to make the environments from (repeatable)")  # fmt: skip
    args = parser.parse_args()
    _check_arguments(parser, args)
    work: Path = args.work.resolve()
    (work / "home").mkdir(parents=True, exist_ok=True)
    cli = [sys.executable, "-m", "cosim.cli"]
    subprocess.run([*cli, "build", "--out", work / "fmus"], check=True, capture_output=True)
    subprocess.run(
        [*cli, "export", "bs-3", "--osp", work / "bs-3-osp", "--fmu-dir", work / "fmus"],
        check=True, capture_output=True,
    )  # fmt: skip
    (work / "runner.py").write_text(RUNNER)
    with_numba, _ = run(sys.executable, work, args.stop)
    numpy_path, _ = run(sys.executable, work, args.stop, AUV_COSIM_NO_JIT="1")
    print(f"the build's Python: its numpy path {apart(with_numba, numpy_path)} to its numba's")
    print(f"{'host':50} {'vs build, numba':>16} {'vs build, numpy':>16}")
    if not args.python:
        for name in HOSTS:
            _row(work, name, host_python(work, name, sys._base_executable), args.stop,  # type: ignore[attr-defined]
                 (with_numba, numpy_path))  # fmt: skip
        return
    built = c_host_run(work, sys.executable, args.stop)[0]
    built_numpy = c_host_run(work, sys.executable, args.stop, AUV_COSIM_NO_JIT="1")[0]
    for base in args.python:
        for name in NEWEST:
            python = host_python(work, name, base)
            _row(work, f"CPython {_version(python)}, {name}", python, args.stop,
                 (with_numba, numpy_path))  # fmt: skip
            rows, said = c_host_run(work, python, args.stop)
            print(f"    C host, AUV_FMU_PYTHON: {apart_text(built, rows)} to the build's "
                  f"numba, {apart_text(built_numpy, rows)} to its numpy path")  # fmt: skip
            for line in dict.fromkeys(said):
                print(f"    {line[:300]}")


def _check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse (one line, exit status 2, before anything is built or installed) a run
    length that is no positive finite number of seconds, a work folder that is a file and
    a --python that is no executable file."""
    if not (math.isfinite(args.stop) and args.stop > 0.0):
        parser.error(f"--stop: {args.stop!r} is not a positive finite number of seconds")
    if args.work.exists() and not args.work.is_dir():
        parser.error(f"--work: {str(args.work)!r} is not a folder")
    for python in args.python:
        if not (Path(python).is_file() and os.access(python, os.X_OK)):
            parser.error(f"--python: {python!r} is not an executable file")


def _row(work: Path, name: str, python: Path, stop: float, reference: tuple[list, list]) -> None:
    """One row of the table: ``python`` through fmpy against the build's two paths."""
    rows, said = run(python, work, stop)
    print(f"{name:50} {apart(reference[0], rows):>16} {apart(reference[1], rows):>16}")
    print(f"    installed: {installed(python)}")
    for line in dict.fromkeys(said):
        print(f"    {line[:300]}")


def apart_text(reference: list[str], rows: list[str]) -> str:
    """:func:`apart` of the C host's printed rows (numbers in %.17g)."""
    as_hex = [[float(x).hex() for x in row.split()] for row in reference]
    return apart(as_hex, [[float(x).hex() for x in row.split()] for row in rows])


if __name__ == "__main__":
    main()
