"""Messages about a value a host wrote stay short enough to show (fmu_runtime/log_text.py)."""

from fmu_runtime.log_text import MAX_MESSAGE_CHARS, shortened


def test_a_message_within_the_limit_is_itself() -> None:
    message = "x" * MAX_MESSAGE_CHARS
    assert shortened(message) is message


def test_a_longer_message_keeps_its_start_and_end_and_says_what_was_left_out() -> None:
    message = "unknown vehicle '" + "x" * 10_000_000 + "': expected one of [...]"
    short = shortened(message)
    assert len(short) < MAX_MESSAGE_CHARS + 300
    assert short.startswith("unknown vehicle 'xxx") and short.endswith("': expected one of [...]")
    left_out = len(message) - MAX_MESSAGE_CHARS - 200
    assert f" ... [{left_out} characters left out] ... " in short
