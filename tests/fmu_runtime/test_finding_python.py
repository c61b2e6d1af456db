"""How the FMU's runtime finds a Python in a host without one (fmu_runtime/native/runtime.c),
seen from a C host in a clean environment: the candidates in order, each asked once in a
subprocess whose output never reaches the host, and every way a candidate can be unfit
refused with NULL from fmi2Instantiate and a line, never CPython's fatal error.

Unfit candidates are made to order where a real one is hard to come by: a "Python" that is
a shell script answering the runtime's probe with what a broken installation would say.
The extraction is moved (its record names a build Python that does not exist) and PATH
holds no Python, so only the candidate under test can be used.
"""

from __future__ import annotations

import re
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest
from c_hosts import moved, run_clean
from repo_paths import ROOT

from cosim.fmus.native import OVERRIDE_VARIABLE

OUR_LIBPYTHON = Path(sysconfig.get_config_var("LIBDIR") or "") / (
    sysconfig.get_config_var("INSTSONAME") or ""
)
pytestmark = pytest.mark.skipif(not OUR_LIBPYTHON.is_file(), reason="no shared libpython")
NATIVE = ROOT / "fmu_runtime" / "native"
LINE = re.compile(r"^log host \[(\d)\] \{(\w+)\} (.*)$", re.M)


def _hex(text: str | Path) -> str:
    return str(text).encode().hex()


def fake_python(folder: Path, answer: dict[str, str], stderr: str = "", status: int = 0) -> Path:
    """An executable that answers the runtime's probe with ``answer`` (paths hex-encoded
    as the probe does), writes ``stderr`` and exits with ``status``."""
    lines = " ".join(f"'{key}={value}'" for key, value in answer.items())  # no quote in any
    script = folder / "python3"  # shell builtins only: the host's PATH holds nothing
    script.write_text(
        f"#!/bin/sh\nprintf '%s\\n' {lines}\nprintf '%s' '{stderr}' >&2\nexit {status}\n"
    )
    script.chmod(0o755)
    return script


def our_answer(**changes: str) -> dict[str, str]:
    """What this test process's Python would answer, with ``changes``."""
    major, minor, micro = sys.version_info[:3]
    answer = {
        "version": f"{major}.{minor}.{micro}",
        "implementation": "CPython",
        "libpython": _hex(OUR_LIBPYTHON),
        "base_prefix": _hex(sys.base_prefix),
        "stdlib": _hex(sysconfig.get_path("stdlib")),
        "executable": _hex(sys.executable),
        "path": ":".join(_hex(p) for p in sys.path if p),
        "numpy": "2.0",
        "numba": "no",
        "end": "yes",
    }
    return {**answer, **changes}


def _run_cycles(host, extracted, folder: Path, home: Path, cycles: int, **extra: str):
    return run_clean(
        [host, moved(extracted["AuvPlant"], folder), "AuvPlant", "cycles", cycles, 2],
        home,
        PATH="/nonexistent",
        **extra,
    )


def _run(host, extracted, folder: Path, home: Path, **extra: str):
    return _run_cycles(host, extracted, folder, home, 1, **extra)


def _candidate(done, number: int) -> str:
    """The line of candidate ``number`` (2 is AUV_FMU_PYTHON)."""
    for _, _, text in LINE.findall(done.stdout):
        match = re.match(rf"no Python for this FMU: {number}\. (.*)$", text)
        if match:
            return match.group(1)
    raise AssertionError(f"no line for candidate {number}:\n{done.stdout}")


@pytest.mark.parametrize(
    ("changes", "reason"),
    [
        ({"base_prefix": _hex("/nonexistent"), "stdlib": _hex("/nonexistent/lib/python3")},
         r"its base prefix /nonexistent holds no standard library \(no /nonexistent/lib/"
         r"python3/os\.py nor /\S+/python3\d+\.zip\)"),
        ({"version": "3.9.18"}, r"its libpython \S+ is Python \d+\.\d+, not 3\.9"),
        ({"version": "3.8.18"}, r"Python 3\.8\.18 is too old: the FMU needs CPython >= 3\.9"),
        ({"libpython": ""}, r"Python [\d.]+ has no shared libpython \(built without "),
        ({"numpy": "", "numpy_error": _hex("ModuleNotFoundError: No module named 'numpy'")},
         r"cannot import numpy \(ModuleNotFoundError: No module named 'numpy'\); fix: \S+ -m "
         r"pip install numpy"),
        ({"implementation": "PyPy"}, r"is PyPy, not CPython"),
        # numbers that fit no int: sscanf's %d (undefined behaviour) read this one as 3.-1.0
        ({"version": "3.99999999999999999999"},
         r'^\S+: said its version is "3\.99999999999999999999", not major\.minor\.micro'),
        # and this one as 3.11.4, a Python the FMU could use
        ({"version": f"{2**32 + 3}.11.4"},
         rf'^\S+: said its version is "{2**32 + 3}\.11\.4", not major\.minor\.micro'),
    ],
)  # fmt: skip
def test_an_unfit_python_is_refused_with_a_line_not_a_fatal_error(
    changes, reason, host, extracted, tmp_path, clean_home
):
    """A home of another version or none, a libpython of another version, too old, no
    shared libpython, no numpy, not CPython: NULL and the line, the host alive."""
    fake = fake_python(tmp_path, our_answer(**changes))
    done = _run(host, extracted, tmp_path, clean_home, **{OVERRIDE_VARIABLE: str(fake)})
    assert (done.returncode, done.stderr) == (3, ""), done.stdout + done.stderr
    assert "instantiate returned NULL" in done.stdout
    assert re.search(reason, _candidate(done, 2)), _candidate(done, 2)


def _fake_libpython(folder: Path, version: str) -> Path:
    """A library exporting every name the runtime resolves from a libpython (read from
    python.c), not started, whose Py_GetVersion says ``version``."""
    names = re.findall(r'SYMBOL\(\w+, "(\w+)"\)', (NATIVE / "python.c").read_text())
    special = {"Py_GetVersion": f'const char *Py_GetVersion(void) {{ return "{version}"; }}'}
    source = folder / "fake_libpython.c"
    source.write_text(
        "\n".join(special.get(name, f"int {name}(void) {{ return 0; }}") for name in names)
    )
    library = folder / "libpython-fake.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-o", library, source], check=True)
    return library


def test_a_libpython_whose_version_is_no_numbers_is_refused_naming_it(
    host, extracted, tmp_path, clean_home
):
    """A candidate's libpython whose Py_GetVersion starts with a number that fits no int:
    sscanf's %d (undefined behaviour) read it as 3.-1 ("is Python 3.-1, not 3.11");
    refused, with the version as it said it."""
    library = _fake_libpython(tmp_path, "3.99999999999999999999 (fake)")
    fake = fake_python(tmp_path, our_answer(libpython=_hex(library)))
    done = _run(host, extracted, tmp_path, clean_home, **{OVERRIDE_VARIABLE: str(fake)})
    assert "instantiate returned NULL" in done.stdout, done.stdout + done.stderr
    assert _candidate(done, 2) == (
        f"{OVERRIDE_VARIABLE}={fake}: its libpython {library} says its version is "
        '"3.99999999999999999999", not major.minor (whole numbers, each at most 2147483647)'
    )


def _deep_folder(root: Path, length: int) -> Path:
    """A folder under ``root`` whose path is ``length`` bytes long (components of at most
    200 bytes: a file name's limit is 255)."""
    folder = root
    while len(str(folder)) < length:
        folder = folder / ("d" * min(200, length - len(str(folder)) - 1))
    folder.mkdir(parents=True)
    assert len(str(folder)) == length
    return folder


def test_a_path_entry_too_long_to_join_is_passed_over_not_cut_short(
    host, extracted, tmp_path, clean_home
):
    """A PATH entry whose joined path (entry/python3) does not fit the runtime's 4096
    bytes: cut short, it named the file at the first 4095 bytes, here a "python3" the
    entry never held, which was asked and reported as python3 on PATH. Passed over."""
    fake = fake_python(_deep_folder(tmp_path, 4095 - len("/python3")), our_answer(version="3.8.1"))
    assert len(str(fake)) == 4095
    done = run_clean([host, moved(extracted["AuvPlant"], tmp_path), "AuvPlant", "cycles", 1, 1],
                     clean_home, PATH=f"{fake}-not-a-folder")  # fmt: skip
    assert "instantiate returned NULL" in done.stdout, done.stdout + done.stderr
    assert _candidate(done, 4) == "python3 on PATH: not found"


def test_a_path_the_runtime_cannot_hold_whole_is_refused_not_cut_short(
    host, extracted, tmp_path, clean_home
):
    """AUV_FMU_PYTHON, and a libpython a candidate names, one byte longer than the
    runtime's 4095 bytes, whose first 4095 bytes name a file: cut short, that file was
    used (a stand-in "python3", our own libpython through a link). Each is refused with a
    line; nothing is started."""
    deep = _deep_folder(tmp_path, 4095 - len("/python3"))
    link = deep / "python3"
    link.symlink_to(OUR_LIBPYTHON)
    fake = fake_python(tmp_path, our_answer(libpython=_hex(f"{link}x")))
    done = _run(host, extracted, tmp_path, clean_home, **{OVERRIDE_VARIABLE: str(fake)})
    assert "instantiate returned NULL" in done.stdout, done.stdout + done.stderr
    assert _candidate(done, 2) == (
        f"{OVERRIDE_VARIABLE}={fake}: said a libpython path longer than the runtime's 4095 bytes"
    )
    link.unlink()
    fake_python(deep, our_answer())
    done = _run(host, extracted, tmp_path, clean_home, **{OVERRIDE_VARIABLE: f"{link}x"})
    assert "instantiate returned NULL" in done.stdout, done.stdout + done.stderr
    assert _candidate(done, 2) == (
        f"{OVERRIDE_VARIABLE}={str(link)[:200]}...: longer than the runtime's 4095 bytes"
    )


def test_a_build_python_the_runtime_cannot_hold_whole_refuses_the_record(
    host, extracted, tmp_path, clean_home
):
    """The build's Python in resources/fmu_runtime.txt one byte longer than the runtime's
    4095 bytes, whose first 4095 bytes name a Python: cut short, that Python was used.
    Refused, naming the record and the key."""
    fake = fake_python(_deep_folder(tmp_path, 4095 - len("/python3")), our_answer())
    folder = moved(extracted["AuvPlant"], tmp_path)
    record = folder / "resources" / "fmu_runtime.txt"
    record.write_text(re.sub(r"build_python=.*", f"build_python={fake}x", record.read_text()))
    done = run_clean([host, folder, "AuvPlant", "cycles", 1, 1], clean_home,
                     PATH="/nonexistent")  # fmt: skip
    assert "instantiate returned NULL" in done.stdout, done.stdout + done.stderr
    assert f"{record}: build_python is longer than the runtime holds" in done.stdout


def test_what_a_probe_writes_never_reaches_the_host_and_its_last_line_is_said(
    host, extracted, tmp_path, clean_home
):
    fake = fake_python(tmp_path, {}, stderr="Fatal Python error: no encodings", status=1)
    done = _run(host, extracted, tmp_path, clean_home, **{OVERRIDE_VARIABLE: str(fake)})
    assert done.stderr == ""
    assert _candidate(done, 2) == (
        f"{OVERRIDE_VARIABLE}={fake}: exited with status 1 before answering: "
        "Fatal Python error: no encodings"
    )


FATAL_HASH_SEED = (
    'Fatal Python error: config_init_hash_seed: PYTHONHASHSEED must be "random" or an '
    "integer in range [0; 4294967295]"
)


@pytest.mark.parametrize(
    ("stderr", "said"),
    [
        # the fatal line names the variable; the last line only says how far CPython got
        (f"{FATAL_HASH_SEED}\nPython runtime state: preinitialized\n\n", FATAL_HASH_SEED),
        # the exception after the state says what the fatal line cannot (the bad value)
        ("Fatal Python error: init_stdio_encoding: failed to get the Python codec name of "
         "the stdio encoding\nPython runtime state: core initialized\nLookupError: unknown "
         "encoding: bogus\n\nCurrent thread 0x00007f (most recent call first):\n  <no "
         "Python frame>\n",
         "Fatal Python error: init_stdio_encoding: failed to get the Python codec name of the "
         "stdio encoding (LookupError: unknown encoding: bogus)"),
        # no fatal line: the last one, as before
        ("Traceback (most recent call last):\nImportError: no site\n", "ImportError: no site"),
    ],
)  # fmt: skip
def test_a_fatal_python_error_line_is_said_rather_than_the_last(
    stderr, said, host, extracted, tmp_path, clean_home
):
    """A Python that refuses a value of the host's environment at start-up names the
    variable in its "Fatal Python error: " line, then says how far it got: the line said
    was the last ("Python runtime state: preinitialized", "<no Python frame>")."""
    fake = fake_python(tmp_path, {}, stderr=stderr, status=1)
    done = _run(host, extracted, tmp_path, clean_home, **{OVERRIDE_VARIABLE: str(fake)})
    assert done.stderr == ""
    assert _candidate(done, 2) == (
        f"{OVERRIDE_VARIABLE}={fake}: exited with status 1 before answering: {said}"
    )


@pytest.mark.parametrize(
    ("variable", "value", "named"),
    [
        ("PYTHONHASHSEED", "garbage", "PYTHONHASHSEED must be"),
        ("PYTHONMALLOC", "x", "PYTHONMALLOC: unknown allocator"),
        ("PYTHONTRACEMALLOC", "x", "PYTHONTRACEMALLOC: invalid number of frames"),
        ("PYTHONIOENCODING", "bogus:xx", "LookupError: unknown encoding: bogus"),
    ],
)
def test_a_real_python_refusing_a_variable_is_refused_by_the_probe_naming_it(
    variable, value, named, host, extracted, tmp_path, clean_home
):
    """This Python with a value it refuses in the host's environment: the probe's child
    refuses it, so the runtime never starts it in the host (where CPython's start-up
    would end the host with the same fatal error: exit status 1, the error on the
    host's stderr); the candidate's line names the variable."""
    done = _run(host, extracted, tmp_path, clean_home,
                **{OVERRIDE_VARIABLE: sys.executable, variable: value})  # fmt: skip
    assert (done.returncode, done.stderr) == (3, ""), done.stdout + done.stderr
    line = _candidate(done, 2)
    assert line.startswith(
        f"{OVERRIDE_VARIABLE}={sys.executable}: exited with status 1 before answering: "
        "Fatal Python error: "
    ), line
    assert named in line, line


@pytest.mark.parametrize("value", ["7", "0", "yes"])
def test_a_pythonutf8_the_host_start_ignores_does_not_refuse_the_python(
    value, host, extracted, tmp_path, clean_home
):
    """PYTHONUTF8=7 in the host's environment: the probe's child refused it ("Fatal
    Python error: preconfig_init_utf8_mode: invalid PYTHONUTF8 environment variable
    value"), so the Python was passed over, though the runtime starts it in the host in
    UTF-8 mode, set before CPython reads its environment, which then never reads
    PYTHONUTF8 at all (any value). The probe asks its child without it, as the Python it
    will start: the FMU runs."""
    done = _run(host, extracted, tmp_path, clean_home,
                **{OVERRIDE_VARIABLE: sys.executable, "PYTHONUTF8": value})  # fmt: skip
    assert "cycles: 1 x 2 ok" in done.stdout, done.stdout + done.stderr
    assert done.stderr == ""


STDLIB_HINT = (
    " (the environment's PYTHONPATH holds a Python's standard library, {}, which a Python "
    "of another version cannot start with: unset PYTHONPATH, or leave that folder out of it)"
)


def test_a_standard_library_on_pythonpath_is_named_with_the_fix(
    host, extracted, tmp_path, clean_home
):
    """A host whose PYTHONPATH holds another Python's standard library: every candidate
    dies before answering (CPython 3.9's sre_compile asserts), and the line names that
    folder and the fix, not only the assertion."""
    stdlib = tmp_path / "lib" / "python3.9"
    stdlib.mkdir(parents=True)
    (stdlib / "os.py").touch()
    fake = fake_python(tmp_path, {}, stderr="AssertionError: SRE module mismatch", status=1)
    pythonpath = f"{tmp_path / 'elsewhere'}:{stdlib}"
    done = _run(host, extracted, tmp_path, clean_home,
                **{OVERRIDE_VARIABLE: str(fake), "PYTHONPATH": pythonpath})  # fmt: skip
    assert done.stderr == ""
    assert _candidate(done, 2) == (
        f"{OVERRIDE_VARIABLE}={fake}: exited with status 1 before answering: "
        "AssertionError: SRE module mismatch" + STDLIB_HINT.format(stdlib)
    )


OTHER_STDLIB = Path("/root/.pyenv/versions/3.9.18/lib/python3.9")


@pytest.mark.skipif(
    not OTHER_STDLIB.is_dir() or sys.version_info[:2] == (3, 9),
    reason=f"needs another CPython's standard library at {OTHER_STDLIB} (pyenv's 3.9.18)",
)
def test_a_real_python_given_another_versions_standard_library_says_so(
    host, extracted, tmp_path, clean_home
):
    """This Python, started by the runtime with CPython 3.9's standard library on PYTHONPATH,
    fails as it does in a user's host; its line names that folder."""
    done = _run(host, extracted, tmp_path, clean_home,
                **{OVERRIDE_VARIABLE: sys.executable, "PYTHONPATH": str(OTHER_STDLIB)})  # fmt: skip
    assert "instantiate returned NULL" in done.stdout, done.stdout + done.stderr
    assert _candidate(done, 2).endswith(STDLIB_HINT.format(OTHER_STDLIB)), _candidate(done, 2)


@pytest.mark.slow
def test_a_virtual_environment_folder_is_used_and_a_venv_without_numpy_passed_over(
    host, extracted, tmp_path, clean_home
):
    """``AUV_FMU_PYTHON`` naming a venv's folder: its bin/python3 is asked (here a venv
    without numpy: refused, with the fix), then the same venv's Python with numpy."""
    bare = tmp_path / "bare"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", bare], check=True)
    done = _run(host, extracted, tmp_path, clean_home, **{OVERRIDE_VARIABLE: f"{bare}/"})
    assert "instantiate returned NULL" in done.stdout and done.stderr == ""
    line = _candidate(done, 2)
    assert line.startswith(f"{OVERRIDE_VARIABLE}={bare}/: Python "), line
    assert "cannot import numpy (ModuleNotFoundError: No module named 'numpy'); fix: " in line
    assert re.search(rf"fix: {re.escape(str(bare))}/+bin/python3 -m pip install numpy$", line)

    with_numpy = tmp_path / "with-numpy"  # this environment's packages, seen through a venv
    subprocess.run(
        [sys.executable, "-m", "venv", "--without-pip", "--system-site-packages", with_numpy],
        check=True,
    )
    base = Path(sys.base_prefix)
    if not (base / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" /
            "site-packages" / "numpy").is_dir():  # fmt: skip
        pytest.skip("the base Python of this environment has no numpy")
    done = _run(host, extracted, tmp_path, clean_home, **{OVERRIDE_VARIABLE: str(with_numpy)})
    # the only candidate there is: the build's Python is gone, PATH holds none
    assert "cycles: 1 x 2 ok" in done.stdout, done.stdout + done.stderr


@pytest.mark.slow
def test_a_libpython_already_in_the_process_is_never_joined_by_another(
    host, extracted, tmp_path, clean_home
):
    """A host that loaded another libpython (here preloaded, not started): every candidate
    using a different libpython is refused; one using that file is used."""
    others = [
        lib
        for lib in Path(sys.base_prefix).parent.glob("3.*/lib/libpython3.*.so.1.0")
        if lib.resolve() != OUR_LIBPYTHON.resolve()
    ]
    if not others:
        pytest.skip("no other shared libpython beside this Python's")
    fake = fake_python(tmp_path, our_answer())
    done = _run(host, extracted, tmp_path, clean_home, LD_PRELOAD=str(others[0]),
                **{OVERRIDE_VARIABLE: str(fake)})  # fmt: skip
    assert "instantiate returned NULL" in done.stdout and done.stderr == ""
    assert f"but {others[0]} is already loaded in this process" in _candidate(done, 2)
    assert _candidate(done, 1).startswith(f"the Python running in this process: {others[0]}")
    done = _run(host, extracted, tmp_path, clean_home, LD_PRELOAD=str(OUR_LIBPYTHON),
                **{OVERRIDE_VARIABLE: str(fake)})  # fmt: skip
    assert "cycles: 1 x 2 ok" in done.stdout, done.stdout + done.stderr


EMPTY_SLOT = re.compile(r"(\s{2}|\(\)|''|(?<![<>=!])=\s|=$|:\s*:|:\s*$|\s$|\(\s|\s\))")


def test_messages_never_name_an_empty_path(host, extracted, tmp_path, clean_home):
    """A garbage record (no build Python), an empty AUV_FMU_PYTHON, a Python that answers
    nothing: every line names what it is about."""
    folder = moved(extracted["AuvPlant"], tmp_path)
    record = folder / "resources" / "fmu_runtime.txt"
    record.write_text(re.sub(r"build_python=.*", "build_python=", record.read_text()))
    silent = fake_python(tmp_path, {})
    for value in ("", str(silent)):
        done = run_clean([host, folder, "AuvPlant", "cycles", 1, 1], clean_home,
                         PATH="/nonexistent", **{OVERRIDE_VARIABLE: value})  # fmt: skip
        texts = [text for _, _, text in LINE.findall(done.stdout)]
        assert len(texts) == 5, done.stdout
        assert [t for t in texts if EMPTY_SLOT.search(t)] == []
        assert "the build's Python: not recorded in resources/fmu_runtime.txt" in texts[2]


@pytest.mark.slow
def test_each_candidate_is_asked_once_per_process(host, extracted, tmp_path, clean_home):
    """Three instantiate/free cycles in one host: the candidate's probe ran once."""
    calls = tmp_path / "calls"
    fake = fake_python(tmp_path, our_answer())
    fake.write_text(fake.read_text().replace("#!/bin/sh\n", f"#!/bin/sh\necho x >> {calls}\n"))
    done = _run_cycles(host, extracted, tmp_path, clean_home, 3, **{OVERRIDE_VARIABLE: str(fake)})
    assert "cycles: 3 x 2 ok" in done.stdout, done.stdout + done.stderr
    assert calls.read_text() == "x\n"


def _answering_at_once(folder: Path, answer: dict[str, str], chatter: int) -> Path:
    """A candidate that writes ``chatter`` lines the probe's reader skips (as a Python whose
    start-up prints lines of its own does) before ``answer``, then waits until a second
    process of it has written its answer too (each leaves a file in ``folder``) to end:
    two probes of it end at the same moment, and their answers are read at once, for as
    long as a loaded machine may keep a thread from finishing its reading."""
    fake = fake_python(folder, answer)
    lines = "\n".join(["."] * chatter)
    wait = (
        f': > "{folder}/answered.$$"\n'
        f'set -- "{folder}"/answered.*\n'
        "n=0\n"  # bounded: a lone probe still ends
        "while [ $# -lt 2 ] && [ $n -lt 100000 ]; do n=$((n+1)); "
        f'set -- "{folder}"/answered.*; done\n'
    )
    text = fake.read_text().replace("#!/bin/sh\n", f"#!/bin/sh\nprintf '%s\\n' '{lines}'\n")
    fake.write_text(text.replace("\nexit ", f"\n{wait}exit "))
    return fake


@pytest.mark.slow
def test_two_copies_reading_their_probes_at_once_both_find_python(
    host, extracted, tmp_path, clean_home
):
    """Two extractions' first instances made at once from two threads (a parallel master):
    each copy of the runtime probes the candidate in its thread, and here both read the
    answer at the same moment. The reader kept its place in the C library's one strtok
    state, shared by every thread: a thread went on in the other's answer, one missed lines
    of its own ("race: 9 0", or "race: 9 9" as seen in a test suite on a machine at load
    20, where a thread is often stopped mid-reading), or read freed memory (a crash). Ten
    fresh processes (before, about seven in ten failed)."""
    fake = _answering_at_once(tmp_path, our_answer(), chatter=400_000)
    first, second = moved(extracted["AuvPlant"], tmp_path), moved(extracted["AuvPlant"], tmp_path)
    for run in range(10):
        for answered in tmp_path.glob("answered.*"):
            answered.unlink()
        done = run_clean([host, first, "AuvPlant", "race", second], clean_home,
                         PATH="/nonexistent", **{OVERRIDE_VARIABLE: str(fake)})  # fmt: skip
        assert len(list(tmp_path.glob("answered.*"))) == 2, "the probes were not at once"
        assert (done.returncode, done.stdout.splitlines()[-1:]) == (0, ["race: 0 0"]), (
            run, [text for _, _, text in LINE.findall(done.stdout)], done.stderr[-2000:]
        )  # fmt: skip
