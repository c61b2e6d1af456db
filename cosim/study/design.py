"""The runs of a study: a full-factorial grid, Monte Carlo samples, or both crossed.

Grid points run in file order, the last factor varying fastest. Monte Carlo draws n points
of the unit hypercube, seeded -- independent uniforms (``numpy.random.default_rng``) or a
Latin hypercube (``scipy.stats.qmc.LatinHypercube``) -- and maps each coordinate through
its factor's inverse CDF (``scipy.stats.uniform`` / ``norm``), so both sampling schemes
share one transformation. Each run's id is a hash of its factor values alone, so it does
not depend on the run's position, the number of workers or their order of completion.
"""

from __future__ import annotations

import hashlib
import inspect
import itertools
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cosim.study.factors import Value
from cosim.study.spec import Normal, RandomSpec, StudyError, StudySpec

RUN_ID_HEX = 16  # 64 bits: a collision among 10^6 runs has probability ~3e-8
# Keep unit samples inside (0, 1): the normal's inverse CDF is infinite at 0 and 1.
_UNIT_MARGIN = float(np.finfo(float).eps)


@dataclass(frozen=True)
class PlannedRun:
    """One run: its stable id, its factor values (factor name -> value) and where it is in
    the study's design (:func:`plan`; None for a run made outside one)."""

    id: str
    values: Mapping[str, Value]
    point: int | None = None  # the grid point's number, 0-based (:func:`grid_points`)
    sample: int | None = None  # the random sample's, 0-based; None without [random]


def run_id(values: Mapping[str, Value]) -> str:
    """A stable id from the factor values: the same values always give the same id.

    The values are hashed as canonical JSON (keys sorted; floats as their shortest
    round-trip text, so 0.1 and 0.1000000000000001 differ and 1 differs from 1.0).
    """
    text = json.dumps(dict(values), sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:RUN_ID_HEX]


def grid_points(grid: Mapping[str, list[Value]]) -> list[dict[str, Value]]:
    """The full factorial over the listed values (one empty point for no grid)."""
    names = list(grid)
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*grid.values())]


def random_samples(random: RandomSpec) -> list[dict[str, Value]]:
    """n seeded samples of the random factors (none if n = 0)."""
    names = list(random.factors)
    if random.n == 0 or not names:
        return []
    # imported here: scipy.stats takes ~0.5 s to import, which a grid-only study (and every
    # worker, which imports this module to run a task) would otherwise wait for
    from scipy import stats
    from scipy.stats import qmc

    if random.sampling == "latin-hypercube":
        unit = _latin_hypercube(qmc, len(names), random.n, random.seed)
    else:
        unit = np.random.default_rng(random.seed).random((random.n, len(names)))
    unit = np.clip(unit, _UNIT_MARGIN, 1.0 - _UNIT_MARGIN)
    columns = []
    for j, name in enumerate(names):
        dist = random.factors[name]
        with np.errstate(all="ignore"):  # a law too wide for a float: refused just below
            if isinstance(dist, Normal):
                mean, std = dist.normal
                columns.append(stats.norm.ppf(unit[:, j], loc=mean, scale=std))
            else:
                low, high = dist.uniform
                columns.append(stats.uniform.ppf(unit[:, j], loc=low, scale=high - low))
        if not np.isfinite(columns[-1]).all():
            raise StudyError(
                f"factor {name!r}: {dist.model_dump()} gives samples beyond the largest float "
                f"({np.finfo(float).max:.4g}): expected a narrower law"
            )
    samples = np.column_stack(columns).tolist()  # Python floats
    return [dict(zip(names, row, strict=True)) for row in samples]


def _latin_hypercube(qmc: Any, d: int, n: int, seed: int) -> np.ndarray:
    """n points of scipy's scrambled Latin hypercube in [0, 1)^d, drawn from
    ``numpy.random.default_rng(seed)``. scipy takes the generator as ``rng`` from 1.15
    (SPEC 7) and as ``seed`` before (pyproject allows 1.13): the same points under both."""
    generator = np.random.default_rng(seed)
    keyword = "rng" if "rng" in inspect.signature(qmc.LatinHypercube).parameters else "seed"
    points: np.ndarray = qmc.LatinHypercube(d=d, **{keyword: generator}).random(n)
    return points


def plan(spec: StudySpec, normalize: Mapping[str, Callable[[Value], Value]]) -> list[PlannedRun]:
    """Every run of the study: each grid point with each sample, each run knowing both
    (their numbers, which runs.csv gives each row).

    ``normalize[factor]`` turns a value into the one the scenario will hold (a Real
    factor's integer becomes a float), so a run's id names what actually runs.
    """
    _check_listed_once(spec.grid, normalize)
    points = grid_points(spec.grid)
    drawn = random_samples(spec.random)
    samples = drawn or [{}]
    runs = []
    for (p, point), (k, sample) in itertools.product(enumerate(points), enumerate(samples)):
        values = {name: normalize[name](value) for name, value in {**point, **sample}.items()}
        runs.append(PlannedRun(run_id(values), values, p, k if drawn else None))
    ids = [run.id for run in runs]
    if len(set(ids)) != len(ids):
        twice = next(run for run in runs if ids.count(run.id) > 1)
        shown = ", ".join(f"{name} = {value!r}" for name, value in twice.values.items())
        raise StudyError(f"two runs have the same factor values: {shown}")
    return runs


def _check_listed_once(
    grid: Mapping[str, list[Value]], normalize: Mapping[str, Callable[[Value], Value]]
) -> None:
    """Refuse a grid factor listing one value written two ways (an Enumeration's
    ``"lateral"`` and ``1``, a Real's ``1`` and ``1.0``), which would run one run twice,
    naming both entries (the same entry twice, the study file's check refuses)."""
    for name, listed in grid.items():
        seen: dict[str, Value] = {}  # run id of the value alone -> the entry giving it
        for entry in listed:
            value = normalize[name](entry)
            first = seen.setdefault(run_id({name: value}), entry)
            if first is not entry:
                raise StudyError(f"[grid] {name!r}: {first!r} and {entry!r} are one value, "
                                 f"{value!r}: list it once")  # fmt: skip
