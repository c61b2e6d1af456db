"""A path as UTF-8 text: what a run writes into its files and its recording's name."""

from __future__ import annotations

import pytest

from cosim.paths import path_text


@pytest.mark.parametrize(
    ("given", "text"),
    [
        ("runs/Größe 結果 🚀", "runs/Größe 結果 🚀"),  # UTF-8 as it is
        ("runs/gr\udcf6sse", "runs/gr\\xf6sse"),  # a Latin-1 byte, escaped
        ("Pr\udcc3\udcbcfung", "Prüfung"),  # UTF-8 bytes an ASCII locale read as surrogates
        ("x\ud800", "x\\ud800"),  # a surrogate no byte of a name gives
    ],
)
def test_a_path_becomes_text_a_utf8_file_takes(given: str, text: str) -> None:
    assert path_text(given) == text
    text.encode("utf-8")  # strict: no surrogate left
