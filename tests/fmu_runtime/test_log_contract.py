"""What our FMUs hand a host's logger, in both runtimes, checked by a C host
(``hosts/log_host.c``) whose logger formats each message with printf, as hosts that show
an FMU's messages do (OMSimulator, libcosim, ecos, fmusim):

* every message carries the instance name the host gave, whole (a long one, with ``%``
  and non-ASCII characters in it; one that is not UTF-8 is refused), a status from
  fmi2OK to fmi2Fatal and a category the model description declares, and is a UTF-8
  printf format without a conversion (a host's text with ``%s`` in it, quoted in a
  refusal, is shown as written and reads no argument), ending in no line break; a
  refusal quoting a long non-ASCII category cuts it between characters;
* an instance logs nothing per step, nothing while it is freed, and with logging off no
  debug message while its Errors still reach the host, under its own name;
* an instance given no logger writes its messages to stderr as written (``%`` single),
  each with its status;
* all of it with the runtime built with ASan and UBSan, which report nothing.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from c_hosts import SANITIZED_ENVIRONMENT, compiled_host, run_clean, sanitized_build, with_runtime

LOG_HOST_SOURCE = Path(__file__).parent / "hosts" / "log_host.c"
RUNTIMES = {"runtime": "", "pythonfmu": "pythonfmu"}
# 130 bytes, a printf conversion and two-byte characters: longer than a short name buffer
LONG_NAME = "plant%s-" + "\u00e4" * 61


@pytest.fixture(scope="module")
def log_host(tmp_path_factory) -> Path:
    return compiled_host(LOG_HOST_SOURCE, tmp_path_factory.mktemp("log-host"))


def run_host(log_host, extracted, clean_home, runtime: str, *args: str):
    done = run_clean([log_host, extracted["AuvPlant"], "AuvPlant", *args], clean_home,
                     timeout=600, AUV_FMU_RUNTIME=RUNTIMES[runtime])  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_every_message_names_the_instance_as_the_host_gave_it(
    runtime, log_host, extracted, clean_home
):
    """A long instance name (with % and non-ASCII characters) comes back whole in every
    message, in both runtimes: it was cut to 127 bytes, mid-character."""
    done = run_host(log_host, extracted, clean_home, runtime, "contract", LONG_NAME)
    assert "VIOLATION" not in done.stdout, done.stdout
    assert "exit-init 3" in done.stdout, done.stdout


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_an_instance_name_that_is_not_utf8_is_refused_without_a_crash(
    runtime, log_host, extracted, clean_home
):
    """An instanceName with a byte that is no UTF-8 is refused by fmi2Instantiate (NULL,
    one Error naming the byte), in both runtimes: pythonfmu's binary crashed its host
    with SIGSEGV, the runtime failed with Python's UnicodeDecodeError."""
    done = run_clean([log_host, extracted["AuvPlant"], "AuvPlant", "contract", "bad\udcffname"],
                     clean_home, timeout=600, AUV_FMU_RUNTIME=RUNTIMES[runtime])  # fmt: skip
    assert done.returncode == 3, done.stdout[-3000:] + done.stderr[-3000:]
    assert done.stdout.splitlines() == [
        "log [3] {logStatusError} fmi2Instantiate refused: instanceName is not UTF-8 (byte 3 "
        "is 0xFF): FMI 2.0 strings are UTF-8",
        "instantiate returned NULL",
    ], done.stdout


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_messages_are_utf8_printf_safe_and_quote_host_text_as_written(
    runtime, log_host, extracted, clean_home
):
    """Every message is a UTF-8 printf format reading no argument, without a trailing
    line break; a host's text with printf conversions is quoted as written; a refusal of a
    long non-ASCII category cuts it between characters (it cut one in two)."""
    done = run_host(log_host, extracted, clean_home, runtime, "contract", "plant-%s-\u00e4")
    assert "VIOLATION" not in done.stdout, done.stdout
    lines = done.stdout.splitlines()
    for case, status in (("none", 0), ("declared", 0), ("unknown", 3), ("long-unknown", 3)):
        assert f"{case} {status}" in lines, done.stdout
    assert "refused: log%sEvents 100% is not a log category" in done.stdout, done.stdout
    assert "unknown vehicle '%s%n%d 100% \u00e4'" in done.stdout, done.stdout
    assert "exit-init 3" in lines, done.stdout


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_no_message_per_step_and_errors_reach_a_host_with_logging_off(
    runtime, log_host, extracted, clean_home
):
    """Two instances, one instantiated with logging on, one with it off: 500 steps log
    nothing per step (the one with logging on says once how the plant steps, a debug
    message of logPlantSteps), freeing logs nothing, the one with logging on gets its
    debug messages of set-up (which Python runs it; on pythonfmu's binary, that binary
    too), the other none, and its refused call reaches the host under its own name only."""
    done = run_host(log_host, extracted, clean_home, runtime, "volume", "500")
    assert "VIOLATION" not in done.stdout, done.stdout
    counts = {" ".join(line.split()[:2]): line.split()[2] for line in done.stdout.splitlines()
              if line.startswith(("loud ", "quiet "))}  # fmt: skip
    assert counts == {
        "loud instantiate+init": "2" if runtime == "pythonfmu" else "1",
        "quiet instantiate+init": "0",
        "loud steps": "1", "quiet steps": "0",
        "quiet refused": "3", "loud after-refusal": "0", "quiet after-refusal": "1",
        "loud free": "0", "quiet free": "0",
    }, done.stdout  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_without_a_logger_messages_go_to_stderr_as_written_with_their_status(
    runtime, log_host, extracted, clean_home
):
    """With a NULL logger in the callbacks, the FMU writes each message to stderr itself:
    the text as written (it showed every % doubled, the escaping meant for printf) and its
    status (it showed none: an Error read like the debug line before it)."""
    done = run_host(log_host, extracted, clean_home, runtime, "silent")
    assert "silent 3" in done.stdout.splitlines(), done.stdout
    lines = done.stderr.splitlines()
    refusal = [line for line in lines if "fmi2SetDebugLogging refused" in line]
    assert refusal == [
        "silent: [Error] fmi2SetDebugLogging refused: log%sEvents 100% is not a log category"
        " of this FMU (expected one of logStatusWarning,logStatusDiscard,logStatusError,"
        "logStatusFatal,logAll,logPlantSteps)"
    ], done.stderr
    assert any(line.startswith("silent: [OK] the FMU runs in ") for line in lines), done.stderr


@pytest.mark.slow
def test_the_log_contract_holds_under_address_and_undefined_behaviour_sanitizers(
    extracted, clean_home, tmp_path
):
    """The log host's three modes against the runtime built with ASan and UBSan (the
    instance name's copy, the cuts between characters, stderr without a logger): the
    same answers, and no sanitizer report."""
    runtime_so, host = sanitized_build(tmp_path, LOG_HOST_SOURCE, ("-Wall", "-Wextra", "-Werror"))
    folder = with_runtime(extracted["AuvPlant"], runtime_so, tmp_path / "AuvPlant")
    for args in (("contract", LONG_NAME), ("volume", "20"), ("silent",)):
        done = run_clean([host, folder, "AuvPlant", *args], clean_home, **SANITIZED_ENVIRONMENT)
        assert done.returncode == 0, (args, done.stdout[-3000:], done.stderr[-3000:])
        assert "VIOLATION" not in done.stdout, (args, done.stdout[-3000:])
        assert "Sanitizer" not in done.stderr and "runtime error" not in done.stderr, args
