"""Scenario files: TOML to a validated, immutable ``Scenario`` (docs/scenario-example.toml)."""
