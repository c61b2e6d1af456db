"""Our FMUs in non-Python hosts through their runtime (fmu_runtime/native/), each run in a
clean environment (``env -i`` with PATH and HOME only: no preload, no PYTHONPATH), with the
FMU's own runtime and with pythonfmu's binary behind it (``AUV_FMU_RUNTIME=pythonfmu``):

* a minimal FMI 2.0 host in C (``hosts/fmi_host.c``, compiled here with ``-Werror``)
  instantiates, initialises, steps and frees every FMU, many times, and gets fmi2Error for
  each call the standard forbids (the runtime's own checks, made without calling Python);
* what FMI hosts pass that crashed them before (NULL arrays, a NULL instance name, wrong
  GUIDs), one build extracted twice in one process, and a host that exits without
  terminating or freeing: fmi2Error or NULL with one line, never a crash;
* without a usable Python, fmi2Instantiate returns NULL and logs one line per candidate;
  ``AUV_FMU_PYTHON`` set to a virtual environment's folder is used;
* valgrind memcheck finds no invalid access and no definitely lost block in the runtime;
* the ecos command-line program runs the exported bs-3 SSP and matches
  ``auv-cosim run bs-3 --algorithm jacobi --extrapolation none`` to the 6 decimals of its CSV;
* a build on a machine without a C compiler still gives working FMUs, and says so.

Every process runs in its own process group, ended by the test even on failure.
"""

from __future__ import annotations

import csv
import importlib.util
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from urllib.parse import quote

import pytest
from c_hosts import (
    HOST_SOURCE,
    SANITIZED_ENVIRONMENT,
    moved,
    run_clean,
    sanitized_build,
    with_runtime,
)
from elf_symbols import glibc_versions, unresolvable
from repo_paths import ROOT

from cosim.fmus import native
from cosim.fmus.build import FMUS
from cosim.fmus.native import NO_COMPILER, OVERRIDE_VARIABLE, RUNTIME_VARIABLE

RUNTIMES = {"runtime": {}, "pythonfmu": {RUNTIME_VARIABLE: "pythonfmu"}}
ILLEGAL = {  # case printed by the host -> what the standard forbids
    "second-enterInitializationMode": "initialisation mode entered twice",
    "doStep-before-initialisation": "a step before exitInitializationMode",
    "doStep-at-wrong-point": "currentCommunicationPoint is not the end of the last step",
    "setReal-fixed-parameter-after-initialisation": "a fixed parameter after initialisation",
    "terminate-before-initialisation": "fmi2Terminate before initialisation",
    "terminate-in-initialisation-mode": "fmi2Terminate in initialisation mode",
    "second-terminate": "fmi2Terminate twice",
    "setupExperiment-stop-before-start": "a stop time before the start time",
    "doStep-past-stop-time": "a step ending past the stop time given to setupExperiment",
    "getReal-output-before-initialisation": "an output read before it has a value",
}
CANDIDATE_LINE = re.compile(
    r"^log host \[3\] \{logStatusError\} no Python for this FMU: (\d)\. (.+)$"
)


def _statuses(stdout: str) -> dict[str, str]:
    return dict(re.findall(r"^([\w-]+) (\d|NULL|instance)$", stdout, re.M))


def _log_lines(stdout: str, status: int) -> list[str]:
    return re.findall(rf"^log \S+ \[{status}\] \{{(\S+)\}} (.+)$", stdout, re.M)


def test_each_fmu_page_says_its_binary_is_the_runtime_and_how_to_point_it_at_python(
    fmu_paths,
):
    for name in FMUS:
        with zipfile.ZipFile(fmu_paths[name]) as archive:
            page = archive.read("documentation/index.html").decode()
            names = archive.namelist()
        assert f"binaries/linux64/{name}_pythonfmu.so" in names
        assert "runtime" in page and OVERRIDE_VARIABLE in page and RUNTIME_VARIABLE in page


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_a_c_host_in_a_clean_environment_runs_100_cycles_of_1000_steps(
    name, host, extracted, clean_home
):
    done = run_clean([host, extracted[name], name, "cycles", 100, 1000], clean_home)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "cycles: 100 x 1000 ok" in done.stdout


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_a_host_with_logging_on_is_told_which_binary_runs_the_fmu(
    runtime, host, extracted, clean_home
):
    """AUV_FMU_RUNTIME=pythonfmu hands the calls to pythonfmu's binary, unseen before
    (every call answered as on the runtime, input derivatives included): an instance
    instantiated with logging on now says so, and names the library; none says it
    otherwise."""
    done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "illegal"], clean_home,
                     **RUNTIMES[runtime])  # fmt: skip
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    library = extracted["AuvPlant"] / "binaries" / "linux64" / "AuvPlant_pythonfmu.so"
    said = [line for line in done.stdout.splitlines() if "pythonfmu's own binary" in line]
    assert set(said) == (
        {f"log host [0] {{logAll}} the FMU runs on pythonfmu's own binary {library} "
         f"({RUNTIME_VARIABLE}=pythonfmu)"}
        if runtime == "pythonfmu" else set()
    )  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "runtime"),
    [*((name, "runtime") for name in sorted(FMUS)), ("AuvPlant", "pythonfmu")],
)
def test_calls_the_standard_forbids_return_fmi2error(name, runtime, host, extracted, clean_home):
    """Each forbidden call on a fresh instance returns fmi2Error (3) with one Error logged,
    and the valid call after the refusals still works (0)."""
    done = run_clean([host, extracted[name], name, "illegal"], clean_home, **RUNTIMES[runtime])
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    statuses = _statuses(done.stdout)
    errors = _log_lines(done.stdout, 3)
    ranges = [case for case in statuses if case.endswith("-outside-range")]
    assert set(ILLEGAL) <= set(statuses) and ranges, done.stdout
    assert {case: statuses[case] for case in [*ILLEGAL, *ranges]} == dict.fromkeys(
        [*ILLEGAL, *ranges], "3"
    )
    assert statuses["valid-step-after-refusals"] == "0"
    assert statuses["getReal-parameter-before-initialisation"] == "0"
    assert statuses["valid-terminate-after-refusals"] == "0"
    assert statuses["valid-initialisation-after-refusals"] == "0"
    assert statuses["valid-setup-after-refusals"] == statuses["valid-steps-to-stop-time"] == "0"
    assert len(errors) == len(ILLEGAL) + len(ranges), errors
    assert all(category == "logStatusError" for category, _ in errors), errors
    assert any("refused: expected" in text for _, text in errors), errors
    assert sum("fmi2Terminate refused" in text for _, text in errors) == 3, errors


HOSTILE = [  # what FMI hosts pass: each refused, with one Error line
    "getReal-null-references", "getReal-null-values", "setReal-null-references",
    "setReal-null-values", "getInteger-null-references", "getInteger-null-values",
    "setInteger-null-references", "setInteger-null-values", "getString-null-values",
    "setString-null-values", "setString-null-string", "deSerialize-null-bytes",
    "deSerialize-null-state", "getFMUstate-null-state", "serialize-null-bytes",
    "setInteger-count-overflow", "setBoolean-count-overflow", "deSerialize-size-past-any-array",
]  # fmt: skip
REFUSED_INSTANTIATIONS = [
    "instantiate-null-name", "instantiate-null-guid", "instantiate-wrong-guid",
    "instantiate-null-resources",
]  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_null_arguments_and_wrong_guids_are_refused_not_crashed_on(
    runtime, host, extracted, clean_home
):
    """A NULL value-reference, value, string or byte array (n > 0), a NULL or wrong GUID,
    a NULL instance name or resource location: fmi2Error, or NULL from fmi2Instantiate,
    each with one Error line (never a NULL category), and the instance goes on."""
    done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "hostile"], clean_home,
                     **RUNTIMES[runtime])  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    statuses = _statuses(done.stdout)
    assert {case: statuses.get(case) for case in HOSTILE} == dict.fromkeys(HOSTILE, "3")
    assert {case: statuses.get(case) for case in REFUSED_INSTANTIATIONS} == dict.fromkeys(
        REFUSED_INSTANTIATIONS, "NULL"
    )
    assert statuses["valid-step-after-refusals"] == "0"
    errors = _log_lines(done.stdout, 3)
    assert len(errors) == len(HOSTILE) + len(REFUSED_INSTANTIATIONS), errors
    assert all(category == "logStatusError" for category, _ in errors), errors
    guid = next(text for _, text in errors if "is not this FMU's" in text)
    assert re.search(
        r"GUID \{0{8}-0{4}-0{4}-0{4}-0{12}\} is not this FMU's \([0-9a-f-]{36}\)", guid
    )


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_one_build_extracted_twice_runs_in_one_process(
    runtime, host, extracted, clean_home, tmp_path
):
    """Two extractions of one FMU, an instance of each, the second instantiated while the
    first is in initialisation mode: each goes through its own sequence."""
    second = tmp_path / "second"
    shutil.copytree(extracted["AuvPlant"], second)
    done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "twice", second], clean_home,
                     **RUNTIMES[runtime])  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    cases = [f"{call}-{k}" for call in ("setup", "enter", "exit") for k in (0, 1)]
    assert {case: _statuses(done.stdout).get(case) for case in [*cases, "steps"]} == (
        dict.fromkeys([*cases, "steps"], "0")
    ), done.stdout


@pytest.mark.slow
def test_two_extractions_instantiated_first_at_once_from_threads_start_python_once(
    host, extracted, clean_home, tmp_path
):
    """A parallel master that instantiates each FMU in its own worker thread, in a process
    without Python: each extraction loads its own copy of the runtime, and both copies
    started CPython at once (about one run in two aborted: "Fatal Python error:
    pyinit_core_reconfigure", or a double free). Ten fresh processes, each with both
    first instances initialised and stepped."""
    second = tmp_path / "second"
    shutil.copytree(extracted["AuvPlant"], second)
    for run in range(10):
        done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "race", second], clean_home)
        assert done.returncode == 0 and "race: 0 0" in done.stdout, (
            run, done.stdout[-2000:] + done.stderr[-2000:]
        )  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "runtime"),
    [*((name, "runtime") for name in sorted(FMUS)), ("AuvPlant", "pythonfmu")],
)
def test_instances_stepped_at_once_from_threads_give_the_lone_instances_results(
    name, runtime, host, extracted, clean_home
):
    """As a parallel master (libcosim's worker threads) steps them: two instances made in
    one thread and stepped at once from two others, and one made, stepped and freed in a
    thread of its own, give every output of an instance stepped alone, bit for bit."""
    done = run_clean([host, extracted[name], name, "threads"], clean_home, **RUNTIMES[runtime])
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert re.search(r"^threads: identical over [1-9]\d* outputs$", done.stdout, re.M), done.stdout


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_a_c_host_may_exit_without_terminating_or_freeing(runtime, host, extracted, clean_home):
    done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "abandon"], clean_home,
                     **RUNTIMES[runtime])  # fmt: skip
    assert (done.returncode, done.stdout.splitlines()[-1:]) == (0, ["abandoned"]), (
        done.stdout[-2000:] + done.stderr[-2000:]
    )
    assert done.stderr == ""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_a_serialised_state_changed_cut_or_extended_is_refused(
    runtime, host, extracted, clean_home
):
    """Serialised states a host keeps (on disk, over a network) and gets back changed: a
    byte changed at 64 places over the state, the last byte cut, a byte added; none is
    restored (fmi2Error from fmi2DeSerializeFMUstate or fmi2SetFMUstate), the intact bytes
    are. Before, a changed value-buffer byte was restored as a state nobody saved."""
    done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "corrupt"], clean_home,
                     **RUNTIMES[runtime])  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "corrupt: 0 of 66 accepted" in done.stdout, done.stdout[-3000:]
    assert _statuses(done.stdout)["intact-state-restores"] == "0"


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_fmi2_free_instance_frees_the_states_it_took(runtime, host, extracted, clean_home):
    """A host that never frees its FMU states: fmi2FreeInstance frees those its instance
    took (FMI 2.0: all it allocated), so a state of a freed instance is refused
    (fmi2Error) rather than set; one freed through another instance before is freed once.
    Before, the states outlived their instance, each holding its slave's part."""
    done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "unfreed"], clean_home,
                     **RUNTIMES[runtime])  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "unfreed: free-through-other 0 set-after-free 3" in done.stdout, done.stdout[-3000:]


def _uri_outputs(done: subprocess.CompletedProcess) -> str:
    lines = [line for line in done.stdout.splitlines() if line.startswith("uri:")]
    assert (done.returncode, len(lines)) == (0, 1), done.stdout[-3000:] + done.stderr[-3000:]
    return lines[0]


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_resource_uris_as_hosts_spell_them_load_the_fmu_from_any_folder(
    runtime, host, extracted, clean_home, tmp_path
):
    """An extraction in a folder named with a space and non-ASCII characters, its resources'
    URI spelled as hosts spell it (RFC 8089: percent-encoded after file:///, file:/ or
    file://localhost, the host in any case, RFC 3986, 3.2.2: file://LOCALHOST was taken for
    a host, //LOCALHOST/..., another folder): the outputs of the extraction in a plain
    folder, with either runtime. pythonfmu's binary, which decodes only %20, crashed its
    host on the first three."""
    plain = extracted["AuvPlant"]
    uri = (plain / "resources").as_uri()
    expected = _uri_outputs(run_clean([host, plain, "AuvPlant", "uri", uri], clean_home,
                                      **RUNTIMES[runtime]))  # fmt: skip
    odd = tmp_path / "FMUs für Tests" / "AuvPlant"
    shutil.copytree(plain, odd)
    path = quote(str(odd / "resources"))
    assert "%20f%C3%BCr%20" in path
    for uri in (
        f"file://{path}",
        f"file:{path}",
        f"file://localhost{path}",
        f"FILE://LocalHost{path}",
    ):
        done = run_clean([host, odd, "AuvPlant", "uri", uri], clean_home, **RUNTIMES[runtime])
        assert _uri_outputs(done) == expected, uri


@pytest.mark.slow
def test_a_folder_pythonfmus_binary_cannot_read_is_refused_not_crashed_on(
    host, extracted, clean_home, tmp_path
):
    """A literal "%20" in a folder's name, which pythonfmu's binary would read as a space:
    with it, fmi2Instantiate returns NULL with a line saying why and what loads the FMU
    (it crashed the host); the FMU's own runtime loads it."""
    odd = tmp_path / "release%2050" / "AuvPlant"
    shutil.copytree(extracted["AuvPlant"], odd)
    uri = (odd / "resources").as_uri()
    assert "%2520" in uri
    _uri_outputs(run_clean([host, odd, "AuvPlant", "uri", uri], clean_home))
    done = run_clean([host, odd, "AuvPlant", "uri", uri], clean_home,
                     **RUNTIMES["pythonfmu"])  # fmt: skip
    assert (done.returncode, done.stderr) == (3, ""), done.stdout[-3000:] + done.stderr
    assert "instantiate returned NULL" in done.stdout
    [(category, text)] = _log_lines(done.stdout, 3)
    assert category == "logStatusError"
    assert f'the resources path {odd / "resources"} holds "%20"' in text
    assert f"the FMU's own runtime can ({RUNTIME_VARIABLE} unset)" in text


@pytest.mark.slow
def test_a_garbage_pythonhome_in_the_host_changes_nothing(host, extracted, clean_home):
    """The runtime sets the interpreter's home itself: a host's PYTHONHOME, garbage or of
    another Python, never reaches CPython's start-up (which would kill the host)."""
    mine = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    others = [  # a Python installed beside this one (pyenv), of another version
        str(p) for p in Path(sys.base_prefix).parent.glob("3.*")
        if (p / "lib").is_dir() and not (p / "lib" / mine).is_dir()
    ]  # fmt: skip
    for home in ("/nonexistent/python-home", *others[:1]):
        done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "cycles", 1, 10], clean_home,
                         PYTHONHOME=home)  # fmt: skip
        assert (done.returncode, done.stderr) == (0, ""), done.stdout[-2000:] + done.stderr
        assert "cycles: 1 x 10 ok" in done.stdout


def test_without_a_usable_python_instantiate_returns_null_with_a_line_per_candidate(
    host, extracted, tmp_path
):
    """Each candidate in order, with why it was passed over; nothing on the host's stderr."""
    missing = tmp_path / "no-such-venv"
    done = run_clean(
        [host, moved(extracted["AuvPlant"], tmp_path), "AuvPlant", "cycles", 1, 1],
        tmp_path,
        PATH="/nonexistent",  # no python3 on PATH either
        **{OVERRIDE_VARIABLE: str(missing)},
    )
    assert "instantiate returned NULL" in done.stdout
    assert done.stderr == ""
    lines = [CANDIDATE_LINE.match(line) for line in done.stdout.splitlines()]
    found = [(int(m.group(1)), m.group(2)) for m in lines if m]
    assert [k for k, _ in found] == [1, 2, 3, 4, 5], done.stdout
    text = dict(found)
    assert text[1] == "the Python running in this process: none runs"
    assert text[2] == f"{OVERRIDE_VARIABLE}={missing}: no such file or folder"
    assert text[3].startswith("the build's Python /nonexistent/build-environment/bin/python: ")
    assert "does not exist" in text[3]
    assert text[4] == "python3 on PATH: not found" and text[5] == "python on PATH: not found"


@pytest.mark.parametrize(
    ("change", "said"),
    [
        # sscanf's %u took 2^32 + 4 for value reference 4 (and would any number that
        # does not fit, undefined behaviour): the line was read as another variable's
        (lambda f: f.replace("4", str(2**32 + 4), 1),
         f"value reference {2**32 + 4} is not a whole number from 0 to 100000"),
        # a min longer than its 31 bytes was cut there, its rest read as the max
        (lambda f: f.replace("-", "-0.50000000000000000000000000000000001", 1),
         'a min of at most 31 bytes expected, found "-0.50000000000000000000000000000000001"'),
        (lambda f: f.replace("-", "0.5x", 1), "min 0.5x, max - or start 0 is neither a number"),
    ],
)  # fmt: skip
def test_a_variables_line_that_cannot_be_read_whole_refuses_the_fmu(
    change, said, host, extracted, tmp_path
):
    """A line of resources/fmu_variables.txt with a value reference that does not fit, a
    bound longer than its field or not a number: NULL from fmi2Instantiate and one line
    naming the file, the line and the bad value, never a variable with other rules."""
    folder = moved(extracted["AuvPlant"], tmp_path)
    table = folder / "resources" / native.VARIABLES_FILE
    lines = table.read_text().splitlines()
    number = next(i for i, line in enumerate(lines) if line.startswith("4 "))
    lines[number] = change(lines[number])
    table.write_text("\n".join(lines) + "\n")
    done = run_clean([host, folder, "AuvPlant", "cycles", 1, 1], tmp_path, PATH="/nonexistent")
    assert "instantiate returned NULL" in done.stdout, done.stdout
    expected = f"{table} line {number + 1}: {said}"
    assert any(expected in text for _, text in _log_lines(done.stdout, 3)), done.stdout


def test_a_value_reference_declared_twice_refuses_the_fmu_naming_it(
    host, extracted, tmp_path, clean_home
):
    """Two variables sharing one value reference (an FMI 2.0 alias, which a hand-edited
    modelDescription.xml can declare): the second line of the table overwrote the first's
    rules and slot silently, so a set through one name was checked by the other's rules.
    NULL from fmi2Instantiate and one line naming the reference and both variables."""
    folder = tmp_path / "AuvPlant"
    shutil.copytree(extracted["AuvPlant"], folder)
    table = folder / "resources" / native.VARIABLES_FILE
    lines = table.read_text().splitlines()
    first = next(line for line in lines if line.startswith("4 "))
    alias = " ".join([*first.split(" ")[:-1], "alias_of_4"])
    table.write_text("\n".join([*lines, alias]) + "\n")
    done = run_clean([host, folder, "AuvPlant", "cycles", 1, 1], clean_home)
    assert "instantiate returned NULL" in done.stdout, done.stdout
    expected = (f"{table} line {len(lines) + 1}: value reference 4 is declared twice "
                f"({first.split(' ')[-1]} and alias_of_4): aliases are not supported")  # fmt: skip
    assert any(expected in text for _, text in _log_lines(done.stdout, 3)), done.stdout


def test_a_resource_location_longer_than_the_runtime_holds_is_refused_saying_so(
    host, extracted, tmp_path
):
    """A resource URI whose path is longer than the runtime's 4095 bytes: it was cut
    there, and the refusal named the cut folder's record as missing, a folder the host
    never gave. Refused saying why."""
    path = str(extracted["AuvPlant"])
    while len(path) < 4100:  # the host holds a URI of up to 4199 bytes
        path += "/" + "d" * min(200, 4099 - len(path))
    uri = f"file://{path}"
    done = run_clean([host, extracted["AuvPlant"], "AuvPlant", "uri", uri], tmp_path,
                     PATH="/nonexistent")  # fmt: skip
    assert "instantiate returned NULL" in done.stdout, done.stdout
    expected = "names a path longer than the runtime's 4095 bytes"
    assert any(expected in text for _, text in _log_lines(done.stdout, 3)), done.stdout


def _loader_records(log: str, name: str) -> list[str]:
    """valgrind error records (invalid accesses, definitely lost blocks) made by the
    loader (``<name>.so``, not ``<name>_pythonfmu.so``): the innermost frame in a library
    without debug information, other than valgrind's allocator, is the loader's. (CPython
    and glibc carry debug information here, so their frames name a source file; the
    loader, pythonfmu's library and the extension modules show ``(in <library>)``.) The
    dynamic linker's over-reads in ``strncmp`` while a library loads (glibc's optimised
    string functions, a known valgrind false positive) come from deeper callers."""
    mine = []
    for record in re.split(r"==\d+== \n", log):
        if not re.search(r"Invalid (read|write|free)|definitely lost", record):
            continue
        frames = re.findall(r"(?:at|by) 0x[0-9A-F]+: .*\(in (\S+)\)", record)
        first = next((lib for lib in frames if "vgpreload" not in lib), "")
        if first.endswith(f"/{name}.so"):
            mine.append(record)
    return mine


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
@pytest.mark.parametrize(
    "mode", [["cycles", 2, 20], ["state"], ["hostile"], ["corrupt"], ["unfreed"]]
)
def test_valgrind_finds_nothing_in_the_loader(mode, host, extracted, tmp_path):
    """A C host under memcheck: two instantiate/step/free cycles and the process exit; an
    FMU state saved, serialised, deserialised into another instance and set (the value
    buffers' copies); the hostile arguments (Strings among them). CPython and pythonfmu's
    own reports (their allocations at start-up) are not ours. Serialised states changed,
    cut and extended (the CRC-32 read over each). States a host never freed, freed with
    their instance."""
    log = tmp_path / "memcheck.log"
    command = ["valgrind", "--leak-check=full", f"--log-file={log}", host]
    done = run_clean(
        [*command, extracted["AuvPlant"], "AuvPlant", *mode],
        tmp_path,
        timeout=1800,
        PYTHONMALLOC="malloc",
        # the plant's numpy path: numba and LLVM under memcheck took ~4 of the 5 minutes,
        # and the loader's code is the same whichever path the plant steps with
        AUV_COSIM_NO_JIT="1",
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    text = log.read_text()
    assert "ERROR SUMMARY" in text
    assert _loader_records(text, "AuvPlant") == []


def _ecos() -> tuple[Path, dict[str, str]]:
    """The ecos program of the ecospy package and the one variable it needs beyond PATH
    and HOME: where its TBB library is (ecos's own dependency, not Python's)."""
    from importlib.util import find_spec

    spec = find_spec("ecospy")
    if spec is None or spec.origin is None:
        pytest.skip("ecospy is not installed")
    program = Path(spec.origin).parent / "binaries" / "ecos"
    from cosim.export.ecos_support import tbb_library

    tbb = tbb_library()
    return program, ({"LD_LIBRARY_PATH": str(Path(tbb).parent)} if tbb else {})


ECOS_CSV_PRECISION = 5e-7  # ecos writes 6 decimals: half a unit in the last one


@pytest.mark.slow
def test_the_ecos_command_line_runs_the_ssp_in_a_clean_environment(fmu_paths, tmp_path):
    from cosim.export import export_ssp
    from cosim.scenario.spec import load_scenario

    fmu_dir = fmu_paths["AuvPlant"].parent
    program, tbb = _ecos()
    ecos = tmp_path / "ecos"
    shutil.copyfile(program, ecos)
    ecos.chmod(0o755)  # pip installs it without the executable bit
    scenario = load_scenario("bs-3", fmu_dir).with_overrides(stop_time=10.0)
    export_ssp(scenario, tmp_path / "bs-3.ssp")
    scratch = tmp_path / "tmp"  # ecos unpacks the SSP there and leaves it: not in /tmp
    scratch.mkdir()
    done = run_clean(
        [ecos, "simulate", "--path", "bs-3.ssp", "--stepSize", "0.01", "--stopTime", "10",
         "--parameterSet", "initial", "--logLevel", "warn"],
        tmp_path,
        TMPDIR=str(scratch),
        **tbb,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert [p.name[:9] for p in scratch.iterdir()] == ["ecos_ssp_"]  # its copy went there
    out = tmp_path / "master"
    master = subprocess.run(
        [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--algorithm", "jacobi",
         "--extrapolation", "none", "--stop-time", "10", "--step", "0.01", "--no-rrd",
         "--quiet", "--out", out, "--fmu-dir", fmu_dir],
        capture_output=True, text=True, timeout=900, check=False, cwd=ROOT,
    )  # fmt: skip
    assert master.returncode == 0, master.stderr[-3000:]
    with open(tmp_path / "bs-3.csv", newline="") as f:
        theirs = list(csv.DictReader(f, skipinitialspace=True))
    with open(out / "results.csv", newline="") as f:
        ours = list(csv.DictReader(f))
    assert len(theirs) == len(ours) == 1001
    compared = 0
    for mine, their in zip(ours, theirs, strict=True):
        assert abs(float(mine["time"]) - float(their["time"])) < 1e-9
        for column, value in their.items():
            instance, _, rest = column.partition("::")
            variable = f"{instance}.{rest.removesuffix('[REAL]')}"
            if rest.endswith("[REAL]") and variable in mine:
                expected = float(mine[variable])
                assert abs(float(value) - expected) <= ECOS_CSV_PRECISION * 1.0001, (
                    f"{variable} at t = {mine['time']}: ecos {value}, master {expected}"
                )
                compared += 1
    assert compared > 1000 * 10


NO_COMPILER_BUILD = """
import sys
sys.modules["ziglang"] = None  # as if the ziglang package were not installed
from pathlib import Path
from cosim.fmus.build import build_fmu
print(build_fmu("AuvPlant", Path(sys.argv[1]), force=True))
"""

RUN_PLANT = """
import sys
from fmu_harness import Harness
fmu = Harness(sys.argv[1], u_0=1.5)
print("steps", [fmu.step(0.01) for _ in range(10)])
fmu.close()
"""


@pytest.mark.slow
def test_a_build_without_a_compiler_keeps_pythonfmus_binary_and_says_so(run_python, tmp_path):
    """Without a compiler the FMU keeps pythonfmu's binary alone, says so once and in its
    documentation, declares that it takes no input derivatives (pythonfmu's binary takes
    none: a master then holds its inputs), and steps."""
    bin_dir = tmp_path / "bin"  # PATH without cc or gcc: only this Python
    bin_dir.mkdir()
    (bin_dir / "python").symlink_to(sys.executable)
    env_path = str(bin_dir)
    code = f"import os; os.environ['PATH'] = {env_path!r}\n" + NO_COMPILER_BUILD
    built = run_python(code, tmp_path / "fmus")
    assert built.returncode == 0, built.stderr[-3000:]
    said = [line for line in built.stderr.splitlines() if "no C compiler" in line]
    assert said == [f"auv-cosim build: {NO_COMPILER}"]
    fmu = Path(built.stdout.strip().splitlines()[-1])
    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
        page = archive.read("documentation/index.html").decode()
        description = archive.read("modelDescription.xml").decode()
    assert 'canInterpolateInputs="false"' in description  # pythonfmu's binary takes none
    assert "binaries/linux64/AuvPlant.so" in names
    assert not any(name.endswith("_pythonfmu.so") for name in names)
    assert "built without a C compiler" in page
    ran = run_python(RUN_PLANT, fmu)
    assert ran.returncode == 0, ran.stderr[-3000:]
    assert "steps [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]" in ran.stdout


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("ziglang") is None, reason="ziglang not installed")
def test_a_runtime_built_by_zig_for_glibc_2_17_runs(host, extracted, tmp_path, clean_home):
    """Where there is no cc: ``zig cc -target x86_64-linux-gnu.2.17``."""
    zig = native.Toolchain("zig", (sys.executable, "-m", "ziglang", "cc"), zig=True)
    runtime = tmp_path / "runtime.so"
    done = subprocess.run(native.compile_command(zig, runtime), capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    assert glibc_versions(runtime)[-1] <= (2, 17) and unresolvable(runtime) == []
    folder = with_runtime(extracted["AuvPlant"], runtime, tmp_path)
    done = run_clean([host, folder, "AuvPlant", "cycles", 2, 50], clean_home)
    assert "cycles: 2 x 50 ok" in done.stdout, done.stdout[-2000:] + done.stderr[-2000:]


@pytest.mark.slow
def test_address_and_undefined_behaviour_sanitizers_find_nothing(extracted, tmp_path, clean_home):
    """The runtime and the C host built with ASan and UBSan: cycles, the forbidden calls,
    the hostile arguments, an FMU state's round trip, values read and written from a
    second thread, instances stepped from several, serialised states changed, cut and
    extended, pointers that are no FMU state (a freed one among them), Strings written
    back with the pointers fmi2GetString gave, states freed with their instance, and a
    file://localhost URI run to the end;
    any finding aborts with a report."""
    runtime, host = sanitized_build(tmp_path, HOST_SOURCE)
    folder = with_runtime(extracted["AuvPlant"], runtime, tmp_path)
    uri = f"file://localhost{quote(str(folder / 'resources'))}"
    modes = (["cycles", 2, 20], ["illegal"], ["hostile"], ["state"], ["gil"], ["threads"],
             ["corrupt"], ["strays"], ["strings-back"], ["unfreed"], ["uri", uri])  # fmt: skip
    for mode in modes:
        done = run_clean([host, folder, "AuvPlant", *mode], clean_home, **SANITIZED_ENVIRONMENT)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
        assert "Sanitizer" not in done.stderr and "runtime error" not in done.stderr
