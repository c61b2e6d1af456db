"""Messages kept to a length a host can show: a value a host wrote (a 10 MB string set as a
vehicle's name) is named by its start, not copied whole into every message about it."""

MAX_MESSAGE_CHARS = 2000  # a message's length beyond which its middle is left out


def shortened(message: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``message`` itself up to ``limit`` characters; longer, its first ``limit`` characters
    and its last 200, with how many were left out between them."""
    if len(message) <= limit:
        return message
    tail = message[-200:]
    left_out = len(message) - limit - len(tail)
    return f"{message[:limit]} ... [{left_out} characters left out] ... {tail}"
