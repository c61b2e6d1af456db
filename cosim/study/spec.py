"""Study files: TOML -> a validated :class:`StudySpec`. A study file is data, never code.

Format (every key is checked; unknown keys are errors)::

    scenario = "bs-3"          # a built-in id or a scenario file (relative to this file)
    stop_time = 20.0           # s, optional override of the scenario's stop time
    keep = "none"              # per-run folders: "all", "failed" or "none" [none]
    check_step = false         # also run each at h/2 and h/4: coupling_error.<metric>
                               # columns, as `auv-cosim run --check-step` [false]
    overlay = ["best:yaw_settling_time_s", "worst:yaw_settling_time_s"]
                               # runs drawn together in overlay.rrd [none]: run ids (16 hex
                               # digits), "best:<metric>" (its lowest value),
                               # "worst:<metric>" (highest) or "all"; OVERLAY_CAP runs at most

    [grid]                     # full factorial over the listed values
    "plant.v_0" = [-0.10, -0.05, 0.05, 0.10]
    "controller.k0" = [0.2, 0.5]

    [random]                   # Monte Carlo: n samples, seeded
    n = 100
    seed = 1
    sampling = "random"        # or "latin-hypercube" (scipy.stats.qmc) [random]
    "plant.current_east" = { uniform = [0.0, 0.3] }     # low, high
    "plant.yaw_0" = { normal = [0.0, 0.1] }             # mean, standard deviation

    [metrics]                  # which summary values to collect [all of them]
    collect = ["yaw_settling_time_s", "final.plant.yaw"]

A factor is ``<instance>.<variable>`` (a start value), ``events.<name>.time|ramp``,
``events.<name>.set.<instance>.<variable>`` or ``faults.<name>.<key>``; what it may name is
checked against the scenario (:mod:`cosim.study.factors`). With both a grid and random
factors, every grid point is run with every one of the n samples (the same samples at each
point).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable
from decimal import Decimal
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    StrictBool,
    StrictFloat,
    StrictInt,
    StrictStr,
    Tag,
    ValidationError,
    model_validator,
)
from pydantic_core import ErrorDetails

from cosim.errors import (
    FLAGS,
    CosimError,
    OptionNames,
    did_you_mean_path,
    relative_to,
    shown,
)
from cosim.scenario.checks import (
    ANY_VALUE,
    UNION_TAGS,
    expected_words,
    field_names,
    file_key,
    misplaced_top_level,
    one_problem_per_key,
    table_expected,
    unknown_key,
)
from cosim.scenario.toml_file import UnreadableTomlError, read_toml_file

OVERLAY_CAP = 20  # runs in one overlay recording: more lines than that cannot be told apart
MAX_RUNS = 100_000  # runs in one study unless --max-runs raises it (a day at ~1 run/s)
MAX_RUNS_CEILING = 10_000_000  # --max-runs at most: the design of every run is built first
_RUN_ID = re.compile(r"[0-9a-f]{16}")  # cosim.study.design.run_id
FactorValue = StrictBool | StrictInt | StrictFloat | StrictStr


class StudyError(CosimError):
    """A study that cannot run: the message names the file (or folder) and the key."""


class StudyEndedError(StudyError):
    """A study ended before its last run, by no fault of its runs (a file of the study it
    cannot write, say); ``where`` says what was kept (set by the runner)."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message
        self.where = ""

    def __str__(self) -> str:
        return self.message + (f"; {self.where}" if self.where else "")


class NoRoomError(StudyEndedError):
    """A run could not write its files for want of room (a full disk, a quota, a file size
    limit): every run after it would fail the same way, so the study ends, its row left
    out for ``--resume`` to run again once there is room."""


def _finite(value: float) -> float:
    """``value`` as a float; NaN, an infinity or an int beyond the floats (10**400: TOML
    and a dict hold one) refused as ``cosim.run`` refuses them, the int shortened."""
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise ValueError(f"{shown(value)} is not a finite number")
    return number


Number = Annotated[StrictInt | StrictFloat, AfterValidator(_finite)]


class _Strict(BaseModel):
    model_config: ClassVar[ConfigDict] = ConfigDict(extra="forbid", frozen=True)


class Uniform(_Strict):
    """Uniform on [low, high)."""

    uniform: tuple[Number, Number]

    @model_validator(mode="after")
    def _ordered(self) -> Uniform:
        if not self.uniform[0] < self.uniform[1]:
            raise ValueError(f"uniform = {list(self.uniform)}: expected [low, high], low < high")
        return self


class Normal(_Strict):
    """Normal with this mean and standard deviation."""

    normal: tuple[Number, Number]

    @model_validator(mode="after")
    def _positive_std(self) -> Normal:
        if not self.normal[1] > 0.0:
            raise ValueError(f"normal = {list(self.normal)}: expected [mean, std], std > 0")
        return self


def _distribution_kind(value: Any) -> str | None:
    """The law's name: a key of the TOML table read, the field of the model dumped; None
    (refused, showing the table) for none or more than one law."""
    keys = value if isinstance(value, dict) else getattr(type(value), "model_fields", {})
    kinds = [kind for kind in ("uniform", "normal") if kind in keys]
    return kinds[0] if len(kinds) == 1 else None


Distribution = Annotated[
    Annotated[Uniform, Tag("uniform")] | Annotated[Normal, Tag("normal")],
    Discriminator(
        _distribution_kind,
        custom_error_type="distribution",
        custom_error_message="expected { uniform = [low, high] } or { normal = [mean, std] }",
    ),
]


def dotted(table: dict[str, Any], is_leaf: Callable[[dict[str, Any]], bool]) -> dict[str, Any]:
    """``table`` with its nested tables flattened into dotted names: TOML reads the
    unquoted dotted key ``plant.v_0 = ...`` (or a ``[grid.plant]`` table) as a table
    ``plant`` holding ``v_0``, which is the factor ``"plant.v_0"``. A table for which
    ``is_leaf`` holds is a value, not flattened (a law ``{ uniform = [...] }``). A name
    written both quoted and dotted is refused."""
    flat: dict[str, Any] = {}
    for key, value in table.items():
        if isinstance(value, dict) and value and not is_leaf(value):
            items = {f"{key}.{k}": v for k, v in dotted(value, is_leaf).items()}.items()
        else:
            items = {key: value}.items()
        for name, item in items:
            if name in flat:
                raise ValueError(f"factor {name!r} is given twice (as a quoted and a dotted key)")
            flat[name] = item
    return flat


class RandomSpec(_Strict):
    """``[random]``: the Monte Carlo part; factor keys sit beside n, seed and sampling."""

    n: int = Field(default=0, ge=0, strict=True, description="number of samples")
    seed: int = Field(default=0, ge=0, strict=True)
    sampling: Literal["random", "latin-hypercube"] = "random"
    factors: dict[str, Distribution] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _gather_factors(cls, data: Any) -> Any:
        """Keys with a dot are factors (``"plant.current_east" = {...}``)."""
        if not isinstance(data, dict):
            return data
        data = dotted(data, lambda value: any(not isinstance(v, dict) for v in value.values()))
        plain = {k: v for k, v in data.items() if "." not in k}
        if "factors" in plain:
            raise ValueError("write each factor as its own key, not under 'factors'")
        factors = {k: v for k, v in data.items() if "." in k}
        return {**plain, "factors": factors} if factors else plain


def _within_floats(values: list[Any]) -> list[Any]:
    """A grid's values, none an int beyond the floats (a Real's value is made a float)."""
    for value in values:
        if isinstance(value, int) and not isinstance(value, bool):
            _finite(value)
    return values


def _unique(values: list[Any]) -> list[Any]:
    seen = [(type(v), v) for v in values]
    if len(set(seen)) != len(seen):
        raise ValueError(f"{values!r} lists a value twice")
    return values


class MetricsSpec(_Strict):
    collect: Annotated[list[StrictStr], AfterValidator(_unique)] | None = Field(
        default=None, min_length=1
    )


def _overlay_entry(entry: str) -> str:
    kind, _, metric = entry.partition(":")
    if entry == "all" or _RUN_ID.fullmatch(entry) or (kind in ("best", "worst") and metric):
        return entry
    raise ValueError(
        f"{entry!r}: expected a run id (16 hex digits), 'best:<metric>', 'worst:<metric>' or 'all'"
    )


OverlayEntry = Annotated[StrictStr, AfterValidator(_overlay_entry)]
GridValues = Annotated[
    list[FactorValue],
    Field(min_length=1),
    AfterValidator(_within_floats),
    AfterValidator(_unique),
]


class StudySpec(_Strict):
    """One study file, checked key by key (types, ranges, no unknown keys)."""

    scenario: StrictStr = Field(min_length=1)
    stop_time: Annotated[Number, Field(gt=0.0)] | None = None
    keep: Literal["all", "failed", "none"] = "none"
    check_step: StrictBool = False  # each run's coupling error (docs/coupling.md)
    grid: dict[str, GridValues] = Field(default_factory=dict)
    random: RandomSpec = Field(default_factory=RandomSpec)
    metrics: MetricsSpec = Field(default_factory=MetricsSpec)
    overlay: Annotated[list[OverlayEntry], Field(min_length=1, max_length=OVERLAY_CAP)] | None = (
        None
    )

    @model_validator(mode="before")
    @classmethod
    def _dotted_grid(cls, data: Any) -> Any:
        """Grid factors written as TOML dotted keys (``plant.v_0 = [...]``) or tables."""
        if isinstance(data, dict) and isinstance(data.get("grid"), dict):
            return {**data, "grid": dotted(data["grid"], lambda value: False)}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> StudySpec:
        for name in [*self.grid, *self.random.factors]:
            instance, _, variable = name.partition(".")
            if not instance or not variable:
                raise ValueError(f"factor {name!r}: expected <instance>.<variable>")
        both = sorted(set(self.grid) & set(self.random.factors))
        if both:
            raise ValueError(f"factor {both[0]!r} is both in [grid] and in [random]")
        if self.random.factors and self.random.n == 0:
            raise ValueError("[random] has factors but n = 0: give n > 0 or remove them")
        if self.random.n > 0 and not self.random.factors:
            raise ValueError(f"[random] n = {self.random.n} but no factor to sample")
        if not self.grid and not self.random.factors:
            raise ValueError("the study varies nothing: give [grid] or [random] factors")
        return self

    @property
    def factors(self) -> list[str]:
        """Every factor, grid first, in file order (the table's factor columns)."""
        return [*self.grid, *self.random.factors]


KEYS = field_names(StudySpec)  # every key a study file may hold: mistyped ones' matches


def run_count(spec: StudySpec) -> int:
    """The study's number of runs, counted without building them: grid points x samples."""
    return math.prod(len(values) for values in spec.grid.values()) * max(spec.random.n, 1)


def check_max_runs(max_runs: int, names: OptionNames = FLAGS) -> None:
    """Refuse a ``max_runs`` beyond :data:`MAX_RUNS_CEILING` (or below 1), naming the
    option as ``names`` do (``--max-runs N`` or ``max_runs=N``)."""
    if isinstance(max_runs, bool) or not 1 <= max_runs <= MAX_RUNS_CEILING:
        shown = str(max_runs) if len(str(max_runs)) <= 30 else f"{str(max_runs)[:20]}..."
        raise StudyError(
            f"{names.option('max_runs')}{'' if names.keywords else ' '}{shown}: expected 1 to "
            f"{MAX_RUNS_CEILING} (the runs of "
            "a study are planned in memory before the first one starts)"
        )


def check_size(
    spec: StudySpec, label: str, max_runs: int = MAX_RUNS, names: OptionNames = FLAGS
) -> None:
    """Refuse a study of more than ``max_runs`` runs, before any is built (the design of
    a larger one would take the memory and time of building every run first), and a
    ``max_runs`` beyond :data:`MAX_RUNS_CEILING` (or below 1). ``label`` names the study
    (:func:`study_label`), ``names`` the option (``--max-runs N`` or ``max_runs=N``)."""
    check_max_runs(max_runs, names)
    count = run_count(spec)
    if count > max_runs:
        grid = " x ".join(str(len(values)) for values in spec.grid.values()) or "1"
        raising = "max_runs=N" if names.keywords else "--max-runs N"
        samples = max(spec.random.n, 1)
        raise StudyError(
            f"{label}: {_many(count)} runs ({grid} grid points x {_many(samples, 'd')} "
            f"samples); at most {max_runs} ({raising} raises the cap)"
        )


def _many(count: int, small: str = ".4g") -> str:
    """A count as ``small`` formats it, or beyond 10**300 in powers of ten (1e+400: a
    float's format overflows, and an int of 400 digits is no figure to read)."""
    if count < 10**300:
        return f"{count:{small}}"
    return f"{Decimal(count).normalize():.4g}"


def study_label(path: Path | str) -> str:
    """How a refusal names the study of the file ``path``: ``study file <path>``."""
    return f"study file {path}"


def load_study(path: Path, label: str | None = None) -> StudySpec:
    """Read and validate a study file; :class:`StudyError` names the key and ``label``
    (default: the file, :func:`study_label`)."""
    label = study_label(path) if label is None else label
    if not os.path.lexists(path):
        raise StudyError(
            f"{label}: no such file{did_you_mean_path(Path(path))}{relative_to(Path(path))}; "
            "expected a study .toml file (docs/studies.md)"
        )
    if not (path.is_file() or path.is_dir()):  # a folder: its read names it below
        raise StudyError(
            f"{label}: cannot read it: a pipe or a device, not a file (a study file is read "
            "more than once: `<(...)` gives it once, and a FIFO with no writer never)"
        )
    try:
        data = read_toml_file(path)
    except UnreadableTomlError as exc:
        raise StudyError(f"{label}: {exc}") from None
    return study_from_dict(data, label)


def study_from_dict(data: dict[str, Any], label: str) -> StudySpec:
    """Validate study data (as read from TOML); :class:`StudyError` names the key and
    ``label`` (the study: :func:`study_label`, or what it was given as)."""
    try:
        return StudySpec.model_validate(data)
    except ValidationError as exc:
        raise StudyError(f"{label}: " + one_problem_per_key(exc, _key, _problem)) from None


def _problem(key: str, err: ErrorDetails) -> str:
    """The problem pydantic's error ``err`` finds with the study file's ``key``."""
    message = expected_words(err).removeprefix("Value error, ")
    tags = {part for part in err["loc"] if part in UNION_TAGS}
    misplaced = misplaced_top_level(key, StudySpec)
    if misplaced and key.count(".") == 1:  # [grid] takes it for a factor's values
        return f"key {key!r}{misplaced}"
    if err["type"] == "extra_forbidden":
        return unknown_key(key, StudySpec, KEYS, {RandomSpec: _RANDOM_TAKES})
    if err["type"] == "missing":
        return f"key {key!r} is missing"
    if not key:
        return message
    if tags:  # one failure per union member tried: say what would do
        message = "expected a number" if tags <= {"int", "float"} else ANY_VALUE
    elif err["type"] == "list_type":  # a grid factor's one value, say
        message = f"expected a list of values, [{err.get('input')!r}]"
    elif table_expected(err):
        message = "expected a table"
    return f"key {key!r} = {shown(err.get('input'))}: {message}"


# [random]'s keys in words: its factors are dotted keys beside n, sampling and seed
_RANDOM_TAKES = [
    *sorted(set(RandomSpec.model_fields) - {"factors"}),
    "factors as 'instance.variable' keys",
]


def _key(loc: tuple[Any, ...]) -> str:
    """pydantic's error location as the study file's key: without RandomSpec's gathered
    ``factors`` and the union members tried (tags), which are no keys of the file; a
    top-level key of those names (``[factors]``) is one."""
    return file_key(
        loc,
        lambda i, part: (
            i > 0
            and (
                part in UNION_TAGS | {"uniform", "normal"}
                or (part == "factors" and loc[i - 1] == "random")
            )
        ),
    )
