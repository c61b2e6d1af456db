"""Live runs: steering a running co-simulation from a program (the control endpoint) or
from the terminal (keys), and the session that opens and closes them (docs/live-runs.md)."""
