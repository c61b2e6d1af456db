"""Dask's configuration files, read by the command and by the workers' fork server on the
way to a study's first run, are parsed by libyaml (cosim/study/fork_server.py's
``libyaml_parsing``): the same configuration, ~10x less CPU than PyYAML's own parser."""

from __future__ import annotations

import os
from typing import Any

import dask.config
import pytest
import yaml

from cosim.study import fork_server

libyaml = pytest.mark.skipif(not yaml.__with_libyaml__, reason="PyYAML built without libyaml")


class _PythonParserRefused(yaml.SafeLoader):
    def __init__(self, stream: Any) -> None:
        raise AssertionError("parsed by PyYAML's pure-Python parser")


def _distributed_defaults() -> str:
    import importlib.util

    spec = importlib.util.find_spec("distributed")
    assert spec is not None and spec.submodule_search_locations
    return os.path.join(spec.submodule_search_locations[0], "distributed.yaml")


@libyaml
def test_the_pre_spawn_environment_is_read_by_libyaml(monkeypatch) -> None:
    monkeypatch.setattr(yaml, "SafeLoader", _PythonParserRefused)
    environ = fork_server.pre_spawn_environ()
    assert environ.get("OMP_NUM_THREADS") == "1"


@libyaml
def test_libyaml_reads_the_same_configuration_and_is_put_back() -> None:
    plain = yaml.safe_load
    by_python = list(dask.config.collect_yaml([_distributed_defaults()]))
    with fork_server.libyaml_parsing():
        by_libyaml = list(dask.config.collect_yaml([_distributed_defaults()]))
    assert by_libyaml == by_python and by_python
    assert yaml.safe_load is plain
