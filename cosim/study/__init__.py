"""Studies: parameter sweeps and Monte Carlo over a scenario, one run per Dask task.

``auv-cosim sweep STUDY.toml`` reads a study file (:mod:`cosim.study.spec`), expands it
into runs with stable ids (:mod:`cosim.study.design`), checks every factor against the
scenario (:mod:`cosim.study.factors`, through the adapter :mod:`cosim.study.task`, the one
module that uses ``cosim.run``), runs them on a local or remote Dask cluster
(:mod:`cosim.study.execution`), appends each finished run to ``runs.csv``
(:mod:`cosim.study.table`) and at the end writes ``runs.parquet``, plots and an index
page (:mod:`cosim.study.plots`, :mod:`cosim.study.page`). :mod:`cosim.study.runner`
ties these together.
"""
