"""The dissertation's printed numbers for the tests, from ``docs/dissertation-values.toml``.

``dissertation(key)`` is the value (a float or a float array); ``DISSERTATION[key]`` the
whole :class:`cosim.analysis.reference_values.Reference` (printed digits, unit, source).
"""

import numpy as np
from repo_paths import ROOT

from cosim.analysis.reference_values import Reference, load_reference_values

VALUES_FILE = ROOT / "docs" / "dissertation-values.toml"
DISSERTATION: dict[str, Reference] = load_reference_values(VALUES_FILE)


def dissertation(key: str) -> float | np.ndarray:
    """The printed value ``key`` as a float or a float array (e.g. ``"table_6_2.gains"``)."""
    return DISSERTATION[key].value
