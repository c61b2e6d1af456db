"""Messages kept to a length and shape a host can show: a value a host wrote (a 10 MB string
set as a vehicle's name) is named by its start, not copied whole into every message about
it; a message of many lines (a warning holding a traceback) is said in one."""

MAX_MESSAGE_CHARS = 2000  # a message's length beyond which its middle is left out


def shortened(message: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``message`` itself up to ``limit`` characters; longer, its first ``limit`` characters
    and its last 200, with how many were left out between them."""
    if len(message) <= limit:
        return message
    tail = message[-200:]
    left_out = len(message) - limit - len(tail)
    return f"{message[:limit]} ... [{left_out} characters left out] ... {tail}"


def without_traceback(message: str) -> str:
    """``message`` as one line: its lines joined by spaces, and of a Python traceback in it
    (numba's warning of a ``NUMBA_*`` value it cannot parse holds one) only its last line,
    the exception, since a traceback's file names and source lines say nothing to the user
    of a host or of the command."""
    head, marker, tail = message.partition("Traceback (most recent call last):")
    words = head.split()
    if marker:
        words += next((line for line in reversed(tail.splitlines()) if line.strip()), "").split()
    return " ".join(words)
