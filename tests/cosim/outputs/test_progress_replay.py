"""A resumed run's progress bar: the rows replayed up to the checkpoint are a phase of
their own, and the bar of steps starts past them, so its rate is the stepping's."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.outputs.sinks import ProgressSink


def test_replayed_rows_are_not_counted_as_steps(capsys: pytest.CaptureFixture) -> None:
    """The replayed rows went into the bar as steps: read from results.csv several times
    faster than stepped, they made the bar's first rate high and its time left short."""
    bar = ProgressSink(10, "bs-3")
    bar.replayed_rows = 5
    for count in (3, 3, 4):  # the last replayed row arrives with the first stepped one
        bar.add_rows(np.zeros(count), np.zeros((count, 1)))
    bar.close()
    err = capsys.readouterr().err
    assert "bs-3: replaying the rows to the checkpoint (3 of 5)" in err, err
    assert "(5 of 5)" in err, err
    shown = [int(part.split("/")[0].split()[-1]) for part in err.split("\r") if "/10 " in part]
    assert shown and min(shown) == 5, err  # the bar starts at the checkpoint's row
