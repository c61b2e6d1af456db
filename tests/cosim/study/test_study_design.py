"""Study design: grid order, seeded Monte Carlo and Latin hypercube, stable run ids."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from scipy import stats

from cosim.study.design import plan, random_samples, run_id
from cosim.study.spec import StudyError, study_from_dict


def same(value):
    return value


def spec(**data):
    return study_from_dict({"scenario": "bs-3", **data}, "s.toml")


def test_grid_is_the_full_factorial_last_factor_fastest() -> None:
    s = spec(grid={"plant.v_0": [-0.1, 0.1], "controller.k0": [0.2, 0.5, 1.0]})
    runs = plan(s, {"plant.v_0": same, "controller.k0": same})
    assert [tuple(r.values.values()) for r in runs] == [
        (-0.1, 0.2),
        (-0.1, 0.5),
        (-0.1, 1.0),
        (0.1, 0.2),
        (0.1, 0.5),
        (0.1, 1.0),
    ]


def test_run_id_depends_on_the_values_only() -> None:
    a = run_id({"plant.v_0": 0.1, "controller.k0": 0.5})
    assert a == run_id({"controller.k0": 0.5, "plant.v_0": 0.1})  # order does not matter
    assert a != run_id({"plant.v_0": 0.1, "controller.k0": 0.5000000000000001})
    assert run_id({"plant.variant": 1}) != run_id({"plant.variant": 1.0})
    assert run_id({"plant.variant": 1}) != run_id({"plant.variant": True})
    assert len(a) == 16 and int(a, 16) >= 0


def test_normalize_gives_a_real_factor_one_id_for_1_and_1_0() -> None:
    s = spec(grid={"plant.u_0": [1, 2.0]})
    runs = plan(s, {"plant.u_0": float})
    assert [r.values["plant.u_0"] for r in runs] == [1.0, 2.0]
    assert runs[0].id == run_id({"plant.u_0": 1.0})
    with pytest.raises(StudyError, match=r"'plant.u_0': 1 and 1.0 are one value, 1.0: list"):
        plan(spec(grid={"plant.u_0": [1, 1.0]}), {"plant.u_0": float})


def test_one_value_listed_twice_in_a_grid_names_both_entries() -> None:
    """An Enumeration's name and its number ("lateral" and 1) in one grid were refused as
    "two runs have the same factor values {'plant.variant': 'lateral'}", a raw dict that
    named neither entry."""
    names = {1: "lateral", 2: "horizontal"}

    def variant(value):
        return names.get(value, value)

    grid = {"controller.k0": [0.2, 0.5], "plant.variant": ["lateral", 2, 1]}
    with pytest.raises(StudyError) as refused:
        plan(spec(grid=grid), {"controller.k0": same, "plant.variant": variant})
    assert str(refused.value) == (
        "[grid] 'plant.variant': 'lateral' and 1 are one value, 'lateral': list it once"
    )


@pytest.mark.parametrize("sampling", ["random", "latin-hypercube"])
def test_samples_are_seeded_and_follow_their_laws(sampling: str) -> None:
    def draw(seed: int, n: int = 400) -> np.ndarray:
        random = spec(
            random={
                "n": n,
                "seed": seed,
                "sampling": sampling,
                "plant.current_east": {"uniform": [0.1, 0.3]},
                "plant.yaw_0": {"normal": [0.5, 0.2]},
            }
        ).random
        return np.array([list(s.values()) for s in random_samples(random)])

    a = draw(7)
    assert np.array_equal(a, draw(7)) and not np.array_equal(a, draw(8))
    assert a.shape == (400, 2) and a[:, 0].min() >= 0.1 and a[:, 0].max() < 0.3
    assert stats.kstest(a[:, 0], stats.uniform(0.1, 0.2).cdf).pvalue > 1e-3
    assert stats.kstest(a[:, 1], stats.norm(0.5, 0.2).cdf).pvalue > 1e-3


def test_latin_hypercube_puts_one_sample_in_each_stratum() -> None:
    n = 10
    random = spec(
        random={
            "n": n,
            "seed": 2,
            "sampling": "latin-hypercube",
            "plant.current_east": {"uniform": [0.0, 1.0]},
            "plant.current_north": {"uniform": [-1.0, 0.0]},
        }
    ).random
    samples = np.array([list(s.values()) for s in random_samples(random)])
    assert sorted(np.floor(samples[:, 0] * n).astype(int)) == list(range(n))
    assert sorted(np.floor((samples[:, 1] + 1.0) * n).astype(int)) == list(range(n))


def test_grid_and_samples_cross_with_the_same_samples_at_every_point() -> None:
    s = spec(
        grid={"plant.v_0": [-0.1, 0.1]},
        random={"n": 3, "seed": 1, "plant.current_east": {"uniform": [0.0, 0.3]}},
    )
    runs = plan(s, {"plant.v_0": same, "plant.current_east": same})
    assert len(runs) == 6 and len({r.id for r in runs}) == 6
    first = [r.values["plant.current_east"] for r in runs[:3]]
    assert first == [r.values["plant.current_east"] for r in runs[3:]]
    assert [r.values["plant.v_0"] for r in runs] == [-0.1] * 3 + [0.1] * 3


@pytest.mark.parametrize("sampling", ["random", "latin-hypercube"])
def test_a_study_naming_no_seed_draws_seed_0s_samples_every_time(sampling: str) -> None:
    """docs/studies.md: no seed is seed 0, never a fresh one, so the same file draws the
    same samples in every process."""
    factors = {"plant.current_east": {"uniform": [0.0, 0.3]}}

    def draw(**seed: int) -> list[dict]:
        return random_samples(spec(random={"n": 5, "sampling": sampling, **seed, **factors}).random)

    assert draw() == draw() == draw(seed=0) != draw(seed=1)


def test_latin_hypercube_draws_the_same_points_under_a_scipy_before_rng(monkeypatch) -> None:
    """pyproject allows scipy >= 1.13, whose qmc engines take their generator as ``seed``
    (``rng`` came with scipy 1.15): a Latin hypercube study failed there with a TypeError.
    Under either keyword the points are those of ``default_rng(seed)``."""
    from scipy.stats import qmc

    factors = {"plant.current_east": {"uniform": [0.0, 0.3]}, "plant.v_0": {"normal": [0, 1]}}
    study = spec(random={"n": 6, "seed": 5, "sampling": "latin-hypercube", **factors})
    today = random_samples(study.random)
    installed = qmc.LatinHypercube
    # the keyword the installed scipy takes (seed where the suite runs at pyproject's floors)
    takes = "rng" if "rng" in inspect.signature(installed).parameters else "seed"

    class BeforeRng(installed):  # the signature of scipy 1.13 and 1.14
        def __init__(self, d: int, *, scramble: bool = True, seed=None) -> None:
            super().__init__(d, scramble=scramble, **{takes: seed})

    monkeypatch.setattr(qmc, "LatinHypercube", BeforeRng)
    assert random_samples(study.random) == today
