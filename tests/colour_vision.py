"""Whether two colours of a figure stay apart for a reader with deuteranopia or protanopia.

The simulation is Machado, Oliveira and Fernandes' (2009) for a full dichromat (severity
1.0), applied to linear RGB; the distance is CIE76's Delta E in CIELAB (D65). A Delta E
of about 2 is a just noticeable difference; :data:`APART` is one that names two lines of a
plot apart at a glance.
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import to_rgb

APART = 20.0  # CIE76 Delta E
DICHROMATS = {  # Machado et al. 2009, Table 1, severity 1.0 (linear RGB)
    "deuteranopia": np.array(
        [
            [0.367322, 0.860646, -0.227968],
            [0.280085, 0.672501, 0.047413],
            [-0.011820, 0.042940, 0.968881],
        ]
    ),
    "protanopia": np.array(
        [
            [0.152286, 1.052583, -0.204868],
            [0.114503, 0.786281, 0.099216],
            [-0.003882, -0.048116, 1.051998],
        ]
    ),
}
SRGB_TO_XYZ = np.array(
    [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]
)
D65 = np.array([0.95047, 1.0, 1.08883])


def _linear(rgb: np.ndarray) -> np.ndarray:
    return np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)


def _lab(linear: np.ndarray) -> np.ndarray:
    xyz = SRGB_TO_XYZ @ np.clip(linear, 0.0, 1.0) / D65
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def distance(a: object, b: object, vision: str) -> float:
    """Delta E between matplotlib colours ``a`` and ``b`` as a reader with ``vision`` (a
    key of :data:`DICHROMATS`) sees them."""
    seen = [_lab(DICHROMATS[vision] @ _linear(np.asarray(to_rgb(c)))) for c in (a, b)]
    return float(np.linalg.norm(seen[0] - seen[1]))


def confused(colours: list[object]) -> list[tuple[str, object, object, float]]:
    """The pairs of ``colours`` a dichromat sees closer than :data:`APART`: (vision, a, b,
    Delta E) each."""
    return [
        (vision, a, b, round(d, 1))
        for vision in DICHROMATS
        for k, a in enumerate(colours)
        for b in colours[k + 1 :]
        if (d := distance(a, b, vision)) < APART
    ]
