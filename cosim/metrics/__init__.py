"""Metrics that runs, studies and viewers share: key figures and manoeuvre metrics (a leaf)."""
