"""The LQR heading controller's weights as the dissertation gives them (Sec. 6.3.1): a
module without the design's imports, so that the autopilot's parameters
(:mod:`controller_fmu.autopilot_config`) take them as defaults cheaply."""

from __future__ import annotations

DISSERTATION_Q_Y: tuple[float, ...] = (1.0, 5e3, 1e2, 1e3, 1e3, 1e6)
"""Q_y on y = [r, p, phi, psi, y_v, y_vel] (Sec. 6.3.1)."""
DISSERTATION_R_U = 1.0
"""R_u on the moving-mass command y_d (Sec. 6.3.1)."""
