"""What a recorded block wrote is put back at its end, and only that: a variable written
since by someone else keeps that value, and one it did not write is not touched."""

from __future__ import annotations

import os

import pytest

from cosim import environ_writes

NAMES = [f"AUV_COSIM_TEST_WRITE_{n}" for n in range(4)]


@pytest.fixture
def names(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    for name in NAMES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv(NAMES[1], "caller's")
    yield NAMES
    for name in NAMES:
        os.environ.pop(name, None)


def test_only_what_the_block_wrote_and_still_holds_is_put_back(names: list[str]) -> None:
    fresh, had, overwritten, untouched = names
    with environ_writes.recorded() as writes:
        environ_writes.set_variable(fresh, "1")
        environ_writes.set_variable(had, "1")
        environ_writes.set_variable(had, "2")  # the first write keeps what was before
        environ_writes.set_default(had, "3")  # set already: no write
        environ_writes.set_variable(overwritten, "1")
        os.environ[overwritten] = "another thread's"
        os.environ[untouched] = "another thread's"
        assert writes == {fresh: (None, "1"), had: ("caller's", "2"), overwritten: (None, "1")}
    assert [os.environ.get(name) for name in names] == [
        None,
        "caller's",
        "another thread's",
        "another thread's",
    ]


def test_a_noted_write_of_code_that_cannot_call_it_is_put_back(names: list[str]) -> None:
    """A library's or the model's own write, noted around the call that makes it."""
    with environ_writes.recorded() as writes:
        with environ_writes.noted(names[0], names[1], names[2]):
            os.environ[names[0]] = "library's"
            os.environ[names[1]] = "caller's"  # the same value: no write
        assert writes == {names[0]: (None, "library's")}
    assert os.environ.get(names[0]) is None and os.environ[names[1]] == "caller's"
