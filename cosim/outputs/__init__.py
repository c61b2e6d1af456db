"""A run's outputs: the run folder, results.csv, summary.json and the sinks that write them."""
