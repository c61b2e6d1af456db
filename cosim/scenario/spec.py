"""Scenario files: TOML -> a validated, fully resolved :class:`Scenario`.

The format is stated once, in docs/scenario-example.toml (every key, with comments). Every
problem is a :class:`ScenarioError` naming the file and the key, raised *before* any FMU is
loaded: variable names, types and causalities come from each FMU's ``modelDescription.xml``
(:func:`cosim.fmus.interface.read_interface`, which does not load the binary). Built-in FMU
names are built on first use, or rebuilt when out of date (``cosim.fmus.build.build_fmu``).
:meth:`Scenario.to_toml` writes the resolved scenario, which loads back to an equal one.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import reprlib
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, TypeAlias, get_args

import tomli_w
from pydantic import (
    ConfigDict,
    Field,
    StrictBool,
    StrictFloat,
    StrictInt,
    StrictStr,
    ValidationError,
)
from pydantic_core import ErrorDetails

from cosim.errors import (
    KEYWORDS,
    CosimError,
    OptionNames,
    did_you_mean,
    did_you_mean_path,
    one_line,
    plain,
    relative_to,
    shown,
)
from cosim.fmus.interface import (
    NOT_COSIMULATION,
    FmuInterface,
    FmuInterfaceError,
    read_interface,
)
from cosim.metrics.manoeuvres import KINDS, manoeuvre_columns
from cosim.paths import DEFAULT_FMU_DIR, path_text
from cosim.scenario.arguments import choice_argument, number_argument, seconds_argument
from cosim.scenario.checks import (
    ANY_VALUE,
    UNION_TAGS,
    ReadOnly,
    ScenarioError,
    Source,
    Strict,
    alias_key,
    check_value,
    expected_words,
    field_names,
    file_key,
    home_table,
    literal_guess,
    misplaced_top_level,
    one_problem_per_key,
    split_ref,
    table_expected,
    unknown_key,
    with_article,
)
from cosim.scenario.connection_units import unit_difference
from cosim.scenario.coupling_graph import algebraic_loop, connection_order, feedthrough
from cosim.scenario.timeline_spec import (
    PLAIN_EVENT_NAME,
    Event,
    EventSpec,
    Fault,
    FaultSpec,
    actuator_owners,
    event_table,
    fault_table,
    resolve_events,
    resolve_faults,
)
from cosim.scenario.toml_file import (
    NotTomlError,
    UnreadableTomlError,
    loads_toml,
    read_toml_file,
)

if TYPE_CHECKING:  # numpy is not imported to read a scenario
    import numpy as np

    from cosim.metrics.key_figures import Vehicle
    from plant_fmu.model.parameters import VehicleParameters

SCENARIO_FOLDER = Path(__file__).parents[1] / "scenarios"  # cosim/scenarios
BUILTIN_FMUS = ("AuvPlant", "AuvAutopilot", "AuvGuidance")
FAULT_COLUMN_PREFIX = "fault."  # results.csv column of a fault: "fault.<name>"
MAX_STEPS = 100_000_000  # communication steps per run: more is refused (days of wall clock)
FILE_SUFFIXES = (".toml",)  # a String start value ending so names a file (vehicle sets)
StartValue = StrictBool | StrictInt | StrictFloat | StrictStr
# A start value as Scenario.with_start and cosim.run take it: a numpy scalar of a bool,
# integer or float (what a numpy computation gives) counts as its Python value
StartInput: TypeAlias = "StartValue | np.bool_ | np.integer[Any] | np.floating[Any]"
Algorithm = Literal["jacobi", "gauss-seidel", "adaptive"]
Extrapolation = Literal["none", "linear", "quadratic"]
ErrorEstimate = Literal["extrapolation", "doubling"]  # adaptive: cosim.engine.adaptive
# What a scenario's exchanged values do across a step when it says nothing: extrapolated
# (second order) unless the file names its algorithm as "jacobi" or "gauss-seidel", which
# keeps the held values of the files written before extrapolation existed.
DEFAULT_EXTRAPOLATION: Extrapolation = "quadratic"
EXTRAPOLATION_ORDER: Mapping[str, int] = {"none": 0, "linear": 1, "quadratic": 2}
DEFAULT_TOLERANCE = 1e-3  # adaptive: the error a step may make, relative (docs/coupling.md)
TOLERANCE_RANGE = (0.0, 1.0)  # adaptive: the tolerances taken, both ends excluded
DEFAULT_MAX_STEPS = 64  # adaptive: the longest step in communication steps, by default
DEFAULT_ERROR_ESTIMATE: ErrorEstimate = "extrapolation"  # adaptive (docs/coupling.md)
_NAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]*$"  # an instance name
_NAME = Annotated[str, Field(pattern=_NAME_PATTERN)]
_PLAIN_NAME = r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$"  # a scenario id: a safe folder name
PATTERN_WORDS = {  # each name pattern of a scenario file, as a refusal says it
    _NAME_PATTERN: "a name of ASCII letters (A-Z, a-z), digits and _, not starting with a digit",
    _PLAIN_NAME: "a name of ASCII letters (A-Z, a-z), digits, _, . and -, not starting with . or -",
    PLAIN_EVENT_NAME: "a name of ASCII letters (A-Z, a-z), digits, - and _",
}
# A stop time within this fraction of a step of a whole number of steps counts as whole.
_STEP_TOLERANCE = 1e-9


# --- the file as written (pydantic, every key checked) ------------------------------------


class CouplingSpec(Strict):
    step: float = Field(gt=0.0, allow_inf_nan=False, description="communication step h, s")
    algorithm: Algorithm = "gauss-seidel"
    order: list[_NAME] | None = Field(default=None, description="Gauss-Seidel order")
    step_multiples: dict[_NAME, Annotated[int, Field(ge=1, le=MAX_STEPS)]] = Field(
        default_factory=dict
    )
    extrapolation: Extrapolation | None = Field(
        default=None, description="inputs across a step; default: see DEFAULT_EXTRAPOLATION"
    )
    tolerance: float | None = Field(
        default=None,
        gt=TOLERANCE_RANGE[0],
        lt=TOLERANCE_RANGE[1],
        allow_inf_nan=False,
        description="adaptive: error",
    )
    max_step: float | None = Field(
        default=None, gt=0.0, allow_inf_nan=False, description="adaptive: longest step, s"
    )
    error_estimate: ErrorEstimate | None = Field(default=None, description="adaptive")


class InstanceSpec(Strict):
    fmu: str = Field(min_length=1, description="built-in FMU name or .fmu path")
    start: dict[str, StartValue] = Field(default_factory=dict)
    # fmi2SetDebugLogging before initialisation (FMI 2.0, 2.1.5): every category, or these
    debug_logging: StrictBool | None = None  # None: as log_categories says (given: on)
    log_categories: list[Annotated[str, Field(min_length=1)]] | None = Field(
        default=None, min_length=1
    )


class ConnectionSpec(Strict):
    model_config: ClassVar[ConfigDict] = ConfigDict(
        extra="forbid", frozen=True, strict=True, populate_by_name=True
    )
    from_: str = Field(alias="from", description="<instance>.<output>")
    to: str = Field(description="<instance>.<input>")


class ConnectionsSpec(Strict):
    same_names: bool = True
    remove: list[str] = Field(default_factory=list)
    add: list[ConnectionSpec] = Field(default_factory=list)


class OutputSpec(Strict):
    record: list[str] | None = None
    rrd: bool = True


class ScenarioSpec(Strict):
    """One scenario file, checked key by key (types, ranges, no unknown keys)."""

    id: str | None = Field(default=None, pattern=_PLAIN_NAME)
    summary: str = ""
    stop_time: float = Field(gt=0.0, allow_inf_nan=False, description="s")
    manoeuvre: str | None = Field(default=None, description="cosim.metrics.manoeuvres kind")
    coupling: CouplingSpec
    instances: dict[_NAME, InstanceSpec] = Field(min_length=1)
    connections: ConnectionsSpec = Field(default_factory=ConnectionsSpec)
    output: OutputSpec = Field(default_factory=OutputSpec)
    events: list[EventSpec] = Field(default_factory=list)
    faults: list[FaultSpec] = Field(default_factory=list)


KEYS = field_names(ScenarioSpec)  # every key a scenario file may hold: mistyped ones' matches


# --- the resolved scenario ---------------------------------------------------------------


@dataclass(frozen=True)
class Connection:
    """Real output ``source`` (``"plant.yaw"``) drives Real input ``target``."""

    source: str
    target: str

    @property
    def source_instance(self) -> str:
        return self.source.split(".", 1)[0]

    @property
    def source_variable(self) -> str:
        return self.source.split(".", 1)[1]

    @property
    def target_instance(self) -> str:
        return self.target.split(".", 1)[0]

    @property
    def target_variable(self) -> str:
        return self.target.split(".", 1)[1]


@dataclass(frozen=True)
class Coupling:
    """How the master advances the instances (see ``cosim.engine.master``;
    docs/coupling.md): a scenario's ``[coupling]`` table, resolved.

    Attributes
    ----------
    step : float
        The communication step h, s: how often the instances exchange values (adaptive:
        the first step, and the unit of its grid).
    algorithm : str
        ``"jacobi"`` (all step from the values exchanged at the step's start),
        ``"gauss-seidel"`` (one after another, in ``order``) or ``"adaptive"``
        (Gauss-Seidel with an error-controlled step).
    order : tuple of str
        The Gauss-Seidel order, every instance once.
    step_multiples : mapping
        Instance name -> k: it steps every k*h.
    extrapolation : str
        What an exchanged Real value does across a step: ``"none"`` (held),
        ``"linear"`` or ``"quadratic"`` (extrapolated from its last values).
    tolerance, max_step, error_estimate : float, float, str or None
        Adaptive only (else None): the relative error a step may make (> 0 and < 1), the
        longest step in s, and how a step's error is estimated (``"extrapolation"`` or
        ``"doubling"``).
    """

    step: float  # s, communication step h (adaptive: the first step and the grid unit)
    algorithm: Algorithm
    order: tuple[str, ...]  # Gauss-Seidel order; every instance once
    step_multiples: Mapping[str, int]  # instance -> k: it steps every k*h
    extrapolation: Extrapolation = "none"  # exchanged Real values across a step
    tolerance: float | None = None  # adaptive: relative error a step may make
    max_step: float | None = None  # adaptive: the longest step, s
    error_estimate: ErrorEstimate | None = None  # adaptive: how a step's error is estimated

    @property
    def extrapolation_order(self) -> int:
        """0 (values held over a step), 1 (linear) or 2 (quadratic)."""
        return EXTRAPOLATION_ORDER[self.extrapolation]


def _python_start_value(value: object, ref: str, where: str) -> StartValue:
    """A start value given in Python (:meth:`Scenario.with_start`): a bool, int, float or
    str, or a numpy scalar of one as its Python value; anything else (an array, a Decimal,
    a list) refused, as ``cosim.run(start=...)`` refuses it."""
    value = plain(value)
    if not isinstance(value, bool | int | float | str):
        raise ScenarioError(
            f"scenario file {where}: start value {ref!r} = {shown(value)}: expected a bool, "
            "int, float or str (or a numpy scalar of one)"
        )
    if isinstance(value, str) and "\0" in value:  # no file name holds one (os refuses it)
        raise ScenarioError(
            f"scenario file {where}: start value {ref!r} = {shown(value)}: expected a string "
            "without a NUL byte"
        )
    return value


def _checked_overrides(
    step: object, algorithm: object, extrapolation: object, tolerance: object, estimate: object
) -> dict[str, Any]:
    """:meth:`Scenario.with_overrides`' coupling options by their keys, each checked by
    type as ``cosim.run`` checks it (:mod:`cosim.scenario.arguments`): a ScenarioError
    naming the keyword, not pydantic's coercion of a Decimal or its words for ``True``."""
    return {
        "step": seconds_argument("step", step, ScenarioError),
        "algorithm": choice_argument("algorithm", algorithm, get_args(Algorithm), ScenarioError),
        "extrapolation": choice_argument(
            "extrapolation", extrapolation, get_args(Extrapolation), ScenarioError
        ),
        "tolerance": number_argument("tolerance", tolerance, ScenarioError),
        "error_estimate": choice_argument(
            "error_estimate", estimate, get_args(ErrorEstimate), ScenarioError
        ),
    }


def _move_design_steps(
    data: dict[str, Any], coupling: Coupling, step: float, digital: Collection[str]
) -> None:
    """Each instance's ``design_step`` that is its communication step (within a relative
    1e-9: 3 x 0.1 s is 0.30000000000000004 s) set to its step under the new ``step``, in
    ``data``; a digital controller's (named in ``digital``: :func:`sample_period` > 0, our
    autopilot's only, as its FMU is known, not any start value of that name) kept."""
    for name, instance in data.get("instances", {}).items():
        multiple = coupling.step_multiples.get(name, 1)
        designed = instance.get("start", {}).get("design_step")
        if (
            isinstance(designed, float | int)
            and name not in digital
            and math.isclose(designed, coupling.step * multiple, rel_tol=1e-9)
        ):
            instance["start"]["design_step"] = step * multiple


INSTANCES_HINT = (
    "scenario.with_start({'<instance>.<variable>': value}) or scenario.with_overrides(...) "
    "(a checked copy), or a scenario file"
)


def _start_hint(instance: str) -> str:
    """What an edit of ``instance``'s start values is told to call instead."""
    return f"scenario.with_start({{'{instance}.<variable>': value}}) (a checked copy)"


@dataclass(frozen=True)
class Instance:
    """One FMU instance: its FMU (as referenced and as a file) and explicit start values.

    Attributes
    ----------
    name : str
        The instance's name in the scenario (``plant``), the first part of its columns'
        names (``plant.yaw``).
    fmu : str
        The FMU as the scenario names it: a built-in name (``AuvPlant``) or a path.
    fmu_path : pathlib.Path
        The FMU file, absolute.
    start : mapping
        The start values the scenario sets, variable -> value, in SI units (the FMU's
        declared start for the others: :meth:`Scenario.start_value`); read-only.
    debug_logging : tuple of str or None
        The log categories turned on (``--fmu-log``; ``()``: every one), None: off.
    """

    name: str
    fmu: str  # as written: a built-in name or an absolute path
    fmu_path: Path
    start: Mapping[str, bool | int | float | str]
    interface: FmuInterface = dataclasses.field(repr=False, compare=False)
    # fmi2SetDebugLogging's categories (FMI 2.0, 2.1.5): None, debug logging off; (), every
    # category; else those (its messages of every status are shown: cosim.engine.slave)
    debug_logging: tuple[str, ...] | None = None

    @property
    def model_description(self) -> Any:
        """fmpy's model description of the FMU (for driving it through fmpy)."""
        return self.interface.model_description

    def variable(self, name: str) -> Any:
        """The fmpy ``ModelVariable`` called ``name``."""
        return self.interface.model_variables[name]

    def variables(self, causality: str) -> list[Any]:
        """fmpy ``ModelVariable``s with this causality, in modelDescription order."""
        return [self.variable(v.name) for v in self.interface.with_causality(causality)]

    def files(self) -> dict[str, Path]:
        """Start values that name files (String values ending in :data:`FILE_SUFFIXES`,
        resolved to absolute paths when the scenario was loaded): variable -> file."""
        return {
            name: Path(value)
            for name, value in self.start.items()
            if isinstance(value, str) and value.endswith(FILE_SUFFIXES)
        }


@dataclass(frozen=True)
class Scenario:
    """A fully resolved scenario: what the master, the results and the exporters use.

    Made by :func:`cosim.load_scenario`, read-only, changed by checked copies
    (:meth:`with_start`, :meth:`with_overrides`, :meth:`with_debug_logging`); its file
    again by :meth:`to_toml`.

    Attributes
    ----------
    id : str
        The built-in id (``bs-3``), or a file's ``id`` key, else its name without ``.toml``.
    summary : str
        One line on what the scenario shows.
    source : pathlib.Path or None
        The file it was read from, absolute.
    stop_time : float
        The simulated time it runs to, s.
    coupling : Coupling
        The communication step (s) and how the instances take turns.
    instances : mapping
        Instance name -> :class:`Instance` (its FMU and start values); read-only.
    connections : tuple of Connection
        Each Real output that drives a Real input (``source``, ``target``, as
        ``"<instance>.<variable>"``).
    record : tuple of str
        The ``"<instance>.<variable>"`` columns of the results, in SI units.
    rrd : bool
        Whether a run writes a Rerun recording (``output.rrd``).
    manoeuvre : str or None
        The standard manoeuvre whose metrics the summary gives (docs/manoeuvres.md).
    events, faults : tuple
        The scenario's ``[[events]]`` and ``[[faults]]`` (docs/events.md), times in s.
    unrecorded : tuple of str
        The outputs left out of the results (String ones).
    """

    id: str
    summary: str
    source: Path | None = dataclasses.field(compare=False)  # the file it was read from
    stop_time: float  # s
    coupling: Coupling
    instances: Mapping[str, Instance]
    connections: tuple[Connection, ...]
    record: tuple[str, ...]  # "<instance>.<variable>" columns of results.csv
    rrd: bool
    spec: ScenarioSpec = dataclasses.field(repr=False, compare=False)
    fmu_dir: Path = dataclasses.field(repr=False, compare=False, default=DEFAULT_FMU_DIR)
    # where relative paths in it are resolved from (its file's folder, or the caller's)
    base_dir: Path | None = dataclasses.field(repr=False, compare=False, default=None)
    manoeuvre: str | None = None  # a cosim.metrics.manoeuvres kind: metrics in the summary
    events: tuple[Event, ...] = ()  # cosim.scenario.timeline_spec
    faults: tuple[Fault, ...] = ()
    unrecorded: tuple[str, ...] = ()  # outputs left out of the default record (String)
    # how a refusal names it: its file, with the start values and overrides applied since
    where: str = dataclasses.field(repr=False, compare=False, default="")
    # True once the loader has checked it (_resolve); a copy by dataclasses.replace gets
    # False, since replace copies no init=False field (pickle and copy.deepcopy keep it)
    loaded: bool = dataclasses.field(default=False, init=False, repr=False, compare=False)

    def __repr__(self) -> str:
        """One line (a notebook shows it for a cell ending in a scenario): what it runs and
        its start values, each shortened; not its connections and recorded columns in full
        (the dataclass's repr: some 5,000 characters for bs-3)."""
        short = reprlib.Repr()
        short.maxstring = short.maxother = 40  # a vehicle set given as TOML text
        short.maxdict = 40
        start = {f"{i.name}.{k}": v for i in self.instances.values() for k, v in i.start.items()}
        source = None if self.source is None else str(self.source)
        return (
            f"Scenario(id={self.id!r}, source={source!r}, stop_time={self.stop_time!r}, "
            f"step={self.coupling.step!r}, "
            f"instances={ {i.name: i.fmu for i in self.instances.values()}!r}, "
            f"start={short.repr(start)}, connections=<{len(self.connections)}>, "
            f"record=<{len(self.columns)} columns>, events=<{len(self.events)}>, "
            f"faults=<{len(self.faults)}>)"
        )

    def __hash__(self) -> int:
        """A hash that equal scenarios share (they have the same id, stop time, recorded
        columns and connections), so a scenario goes into a set or keys a dict; the one
        the dataclass would make hashed the read-only start values, which have none."""
        return hash((self.id, self.stop_time, self.record, self.connections))

    def check_loaded(self) -> None:
        """Raise :class:`ScenarioError` unless the loader made this scenario: a copy by
        ``dataclasses.replace`` (or a Scenario made by hand) skipped the checks, and the
        next ``with_start`` or override would start again from the checked file data,
        silently dropping what the copy changed."""
        if not self.loaded:
            raise ScenarioError(
                f"scenario {self.described}: changed by dataclasses.replace (or made by hand), "
                "so not checked; expected scenario.with_start({'<instance>.<variable>': "
                "value}) or scenario.with_overrides(stop_time=..., step=...), or a file"
            )

    @property
    def columns(self) -> tuple[str, ...]:
        """The columns of results.csv after ``time``: ``record``, then ``fault.<name>`` per
        fault (1.0 while it acts, else 0.0)."""
        return self.record + tuple(f"{FAULT_COLUMN_PREFIX}{f.name}" for f in self.faults)

    @property
    def key_instances(self) -> dict[str, str]:
        """The instances the key figures read (:mod:`cosim.metrics.key_figures`), whatever
        the scenario calls them: ``plant``, the first running the plant FMU, and
        ``controller``, the first running the autopilot (by model identifier; the names
        "plant" and "controller" where none does)."""
        models = {name: inst.interface.model_identifier for name, inst in self.instances.items()}
        found = {"plant": "AuvPlant", "controller": "AuvAutopilot"}
        return {
            role: next((name for name, m in models.items() if m == model), role)
            for role, model in found.items()
        }

    @property
    def key_setpoint_source(self) -> str | None:
        """The output a connection drives the key figures' yaw set-point from (the
        ``yaw_setpoint`` of :attr:`key_instances`' controller: a waypoint guidance's
        ``<guidance>.yaw_setpoint``), None if none does (a start value or events set it)."""
        target = f"{self.key_instances['controller']}.yaw_setpoint"
        return next((c.source for c in self.connections if c.target == target), None)

    @property
    def key_vehicles(self) -> list[Vehicle]:
        """The vehicles the key figures describe (:func:`cosim.metrics.key_figures.vehicles`):
        the one of :attr:`key_instances`, or each plant's of several, with its autopilot."""
        from cosim.metrics.key_figures import vehicles  # numpy: not to read a scenario

        models = {name: inst.interface.model_identifier for name, inst in self.instances.items()}
        return vehicles(models, [(c.source, c.target) for c in self.connections])

    @property
    def n_steps(self) -> int:
        """Number of communication steps to the stop time."""
        return round(self.stop_time / self.coupling.step)

    def unconnected_inputs(self, instance: str) -> list[str]:
        """Inputs of ``instance`` that no connection drives (they hold their start value)."""
        driven = {c.target_variable for c in self.connections if c.target_instance == instance}
        return [v.name for v in self.instances[instance].variables("input") if v.name not in driven]

    def start_value(self, instance: str, name: str) -> bool | int | float | str | None:
        """The value ``instance.name`` starts with: the scenario's, else the FMU's declared
        start (converted to its type), else None (no such variable or no start)."""
        inst = self.instances[instance]
        if name in inst.start:
            return inst.start[name]
        var = inst.interface.variables.get(name)
        return None if var is None else var.start

    def with_overrides(
        self,
        stop_time: float | None = None,
        step: float | None = None,
        algorithm: Algorithm | None = None,
        extrapolation: Extrapolation | None = None,
        tolerance: float | None = None,
        error_estimate: ErrorEstimate | None = None,
        names: OptionNames | None = KEYWORDS,
    ) -> Scenario:
        """A re-validated copy with the command line's overrides applied: ``algorithm``
        ``"jacobi"``, ``"gauss-seidel"`` or ``"adaptive"``, ``extrapolation`` ``"none"``,
        ``"linear"`` or ``"quadratic"``, ``error_estimate`` (adaptive) ``"extrapolation"``
        or ``"doubling"`` (:class:`Coupling`). A refusal of
        what they make names them as ``names`` gives options (``--step 1e-09`` on the
        command line, :data:`cosim.errors.FLAGS`; ``step=1e-09`` in Python,
        :data:`~cosim.errors.KEYWORDS`, the default), or, for None, as the scenario keys they
        set (a caller's own settings: a study's ``stop_time``, ``--check-step``'s steps).

        A new step also moves every instance's ``design_step`` start value that equalled
        that instance's old communication step (a sampled controller designed for the step
        it runs at, like the autopilot's discrete LQR), so ``--step`` never leaves a
        controller designed for another sample time; our autopilot with a ``sample_period``
        of its own (a digital controller, :func:`sample_period`) keeps both. An override
        changes what it names only: another algorithm keeps the extrapolation the scenario
        resolved to (naming the algorithm it runs changes nothing) and drops the adaptive
        algorithm's keys.

        ``stop_time`` and ``step`` are in s, ``tolerance`` the adaptive algorithm's relative
        error a step may make (between 0 and 1, docs/coupling.md); None keeps the
        scenario's. Each is checked by type first, as ``cosim.run`` checks it (a numpy
        number as its value; a Decimal, a string or a bool refused). Raises
        :class:`ScenarioError` naming a value the scenario refuses.
        """
        if names is not None and not isinstance(names, OptionNames):
            raise ScenarioError(
                f"names={shown(names)}: expected None or how a refusal names the options, "
                "cosim.errors.FLAGS or KEYWORDS"
            )
        stop_time = seconds_argument("stop_time", stop_time, ScenarioError)
        coupling: dict[str, Any] = {}
        given = _checked_overrides(step, algorithm, extrapolation, tolerance, error_estimate)
        coupling.update({key: value for key, value in given.items() if value is not None})
        data = self.spec.model_dump(by_alias=True, exclude_none=True)
        if "algorithm" not in self.spec.coupling.model_fields_set:
            data["coupling"].pop("algorithm")  # unnamed: the extrapolation keeps its default
        if algorithm is not None:
            data["coupling"].setdefault("extrapolation", self.coupling.extrapolation)
            if algorithm != "adaptive":
                for key in ("tolerance", "max_step", "error_estimate"):
                    data["coupling"].pop(key, None)
        data["coupling"].update(coupling)
        if step is not None:
            digital = {n for n, inst in self.instances.items() if sample_period(inst) > 0.0}
            _move_design_steps(data, self.coupling, step, digital)
        if stop_time is not None:
            data["stop_time"] = stop_time
        named = {"stop_time": stop_time, **{f"coupling.{k}": v for k, v in given.items()}}
        if names is not None:
            options = overridden_keys(names, {"stop_time": stop_time, **given})
            return self._revalidated(data, self.described, options)
        overrides = ", ".join(f"{k} = {v!r}" for k, v in named.items() if v is not None)
        return self._revalidated(data, f"{self.described} (with the override {overrides})")

    def with_start(self, values: Mapping[str, StartInput]) -> Scenario:
        """A re-validated copy with these start values added or replaced.

        ``values`` maps ``"<instance>.<variable>"`` to a value in SI units (a bool, int,
        float or string, as in ``[instances.<instance>.start]``, or a numpy scalar of one,
        taken as its Python value; a file, ``"my-vehicle.toml"``, is relative to the working
        folder, not to the scenario's file); each passes the checks a
        scenario file's start value passes (the variable exists, is a parameter or an
        unconnected input, the value has its type). Raises :class:`ScenarioError`.
        """
        if not isinstance(values, Mapping):
            raise ScenarioError(
                f"start values {shown(values)}: expected a mapping "
                "{'<instance>.<variable>': value}"
            )
        data = self.spec.model_dump(by_alias=True, exclude_none=True)
        given = ", ".join(f"{shown(ref)}: {shown(value)}" for ref, value in values.items())
        where = f"{self.described} (with the start values {{{given}}})"
        for ref, value in values.items():
            instance, dot, variable = ref.partition(".") if isinstance(ref, str) else ("", "", "")
            if not dot or instance not in data["instances"] or not variable:
                raise ScenarioError(
                    f"scenario file {where}: start value {ref!r}: expected '<instance>.<variable>' "
                    f"with an instance of {list(data['instances'])}"
                    + did_you_mean(instance, data["instances"])
                )
            start = data["instances"][instance].setdefault("start", {})
            value = _python_start_value(value, ref, where)
            if isinstance(value, str) and value.endswith(FILE_SUFFIXES):
                value = os.path.abspath(value)  # given in Python: from the working folder
            start[variable] = value
        return self._revalidated(data, where)

    def with_debug_logging(self, logs: Mapping[str, list[str]]) -> Scenario:
        """A re-validated copy with debug logging on for these instances: ``logs`` maps
        an instance's name to the log categories to turn on (``[]``: every category), as
        its ``debug_logging`` and ``log_categories`` keys would (``auv-cosim run
        --fmu-log``). Raises :class:`ScenarioError`."""
        checked = debug_logs(logs, "logs", ScenarioError)
        data = self.spec.model_dump(by_alias=True, exclude_none=True)
        given = "; ".join(f"{name}: {', '.join(c) or 'all'}" for name, c in checked.items())
        where = f"{self.described} (with the debug logging of {given})"
        for name, categories in checked.items():
            if name not in data["instances"]:
                raise ScenarioError(
                    f"scenario file {where}: no instance {name!r}: expected one of "
                    f"{list(data['instances'])}" + did_you_mean(name, data["instances"])
                )
            table = data["instances"][name]
            table["debug_logging"] = True
            if categories:
                table["log_categories"] = list(categories)
            else:
                table.pop("log_categories", None)
        return self._revalidated(data, where)

    @property
    def described(self) -> str:
        """The scenario as a refusal names it (after ``scenario file``): its file or id,
        with the start values and overrides applied since it was read."""
        return self.where or str(self.source or self.id)

    def _revalidated(
        self, data: dict[str, Any], where: str, given: Mapping[str, str] | None = None
    ) -> Scenario:
        """The scenario of the changed file data ``data``, checked like a file; ``given``
        names the keys a caller's options set (:class:`~cosim.scenario.checks.Source`)."""
        self.check_loaded()
        src = Source(where, given or {})
        spec = _validate_spec(data, where, src)
        base_dir = self.base_dir or (self.source.parent if self.source else Path.cwd())
        return _resolve(spec, self.id, self.source, base_dir, self.fmu_dir, src)

    def to_toml(self) -> str:
        """The resolved scenario as a scenario file that loads back to an equal scenario."""
        data: dict[str, Any] = {
            "id": self.id,
            "summary": self.summary,
            "stop_time": self.stop_time,
            "coupling": _coupling_table(self.coupling),
            "instances": {name: _instance_table(inst) for name, inst in self.instances.items()},
            "connections": {
                "same_names": False,
                "remove": [],
                "add": [{"from": c.source, "to": c.target} for c in self.connections],
            },
            "output": {"record": list(self.record), "rrd": self.rrd},
        }
        if self.manoeuvre is not None:
            data["manoeuvre"] = self.manoeuvre
        if self.events:
            data["events"] = [event_table(event) for event in self.events]
        if self.faults:
            data["faults"] = [
                fault_table(f, f.actuator and len(actuator_owners(f.kind, self)) > 1)
                for f in self.faults
            ]
        origin = f" (from {path_text(self.source)})" if self.source else ""
        header = (
            f"# Resolved scenario {self.id!r}{origin}.\n"
            "# Every connection, start value, step multiple and recorded variable is spelled\n"
            "# out; run it with `auv-cosim run <this file>`.\n"
        )
        return header + tomli_w.dumps(data)


def log_category_problem(interface: FmuInterface, categories: list[str]) -> str | None:
    """Why ``categories`` cannot be given to the FMU's ``fmi2SetDebugLogging`` (one that
    its ``<LogCategories>`` do not declare, or any, when it declares none), None if they
    can (FMI 2.0, 2.1.5: the categories are the FMU's)."""
    declared, model = interface.log_categories, interface.model_identifier
    if not declared:
        return (
            f"{model} declares no LogCategories (its modelDescription.xml): "
            "debug logging of all of its messages takes no category"
        )
    for category in categories:
        if category not in declared:
            guess = did_you_mean(category, declared)
            return (
                f"{category!r} is not a log category of {model}{guess}: "
                f"expected one of {', '.join(declared)}"
            )
    return None


def _instance_table(instance: Instance) -> dict[str, Any]:
    """``[instances.<name>]`` as :meth:`Scenario.to_toml` writes it (its debug logging keys
    only when on, as an earlier version wrote none)."""
    table: dict[str, Any] = {"fmu": instance.fmu, "start": dict(instance.start)}
    if instance.debug_logging is not None:
        table["debug_logging"] = True
        if instance.debug_logging:
            table["log_categories"] = list(instance.debug_logging)
    return table


def _coupling_table(coupling: Coupling) -> dict[str, Any]:
    """``[coupling]`` as :meth:`Scenario.to_toml` writes it: every key spelled out."""
    table: dict[str, Any] = {
        "step": coupling.step,
        "algorithm": coupling.algorithm,
        "order": list(coupling.order),
        "step_multiples": dict(coupling.step_multiples),
        "extrapolation": coupling.extrapolation,
    }
    if coupling.algorithm == "adaptive":
        table.update(tolerance=coupling.tolerance, max_step=coupling.max_step,
                     error_estimate=coupling.error_estimate)  # fmt: skip
    return table


# --- loading -----------------------------------------------------------------------------


def builtin_scenarios() -> dict[str, str]:
    """Built-in scenario ids -> one-line summaries (read without touching any FMU)."""
    result = {}
    for path in sorted(SCENARIO_FOLDER.glob("*.toml"), key=_natural_key):
        spec = _validate_spec(_read_toml(path), str(path))
        result[spec.id or path.stem] = spec.summary
    return result


def scenario_path(id_or_path: str | Path, given: str | None = None) -> Path:
    """The file of a built-in scenario id, or ``id_or_path`` itself if it is a file.
    ``given``: how a refusal of a path that is no file names it (the API's
    ``scenario='runs'``; default: the path alone, as the command line's argument)."""
    try:
        return _scenario_file(id_or_path, given)
    except (OSError, ValueError) as exc:  # a name too long, a NUL: never looked up
        if isinstance(exc, UnicodeError):  # a locale's encoding: said where it is caught
            raise
        raise ScenarioError(
            f"{given or f'scenario {shown(str(id_or_path))}'}: cannot look it up: "
            f"{unusable_path(exc)}; expected a built-in id or the path of a scenario .toml file"
        ) from None


def unusable_path(exc: OSError | ValueError) -> str:
    """Why the system could not look a path up (``exc``), in a few words."""
    if isinstance(exc, ValueError):  # os.stat's "embedded null byte"
        return "a path holds no NUL character"
    return exc.strerror or str(exc)


def _scenario_file(id_or_path: str | Path, given: str | None) -> Path:
    """:func:`scenario_path`'s look-up, which the system may refuse (OSError, ValueError)."""
    candidate = SCENARIO_FOLDER / f"{id_or_path}.toml"
    if "/" not in str(id_or_path) and candidate.is_file():
        return candidate
    path = Path(id_or_path)
    if path.is_file():
        return path
    if _looks_like_a_path(str(id_or_path)) or os.path.lexists(path):
        exists = os.path.lexists(path)
        if path.exists() and not path.is_dir():  # a link to nothing: "not a file" below
            raise ScenarioError(
                f"scenario file {one_line(str(id_or_path))}: cannot read it: a pipe or a "
                "device, not a file (a scenario file is read more than once: `<(...)` gives it "
                "once, and a FIFO with no writer never); write it to a file first"
            )
        guess = "" if exists else did_you_mean_path(path)
        if not (exists or guess) and _is_builtin_file_name(path):
            guess = f" (the built-in scenario is the id {path.stem!r}, without .toml)"
        what = "not a file" if exists else "no such file"
        named = f"{given}: {what}" if given else f"{what}: {one_line(str(id_or_path))}"
        raise ScenarioError(f"{named}{guess}{relative_to(path)}; expected a scenario .toml file")
    guess = (
        did_you_mean(str(id_or_path), builtin_scenarios())
        or _with_toml(path)
        or did_you_mean_path(path)
    )
    raise ScenarioError(
        f"unknown scenario {str(id_or_path)!r}{guess}:"
        f" expected a built-in id ({', '.join(builtin_scenarios())}) or the path of a scenario "
        ".toml file"
    )


def _with_toml(path: Path) -> str:
    """`` (did you mean 'lab1.toml'?)`` for ``lab1`` beside a file ``lab1.toml`` (a name
    without .toml is read as a built-in id), else ``""``."""
    if not path.name:  # "" or ".": no name to add .toml to
        return ""
    named = path.with_name(f"{path.name}.toml")
    return f" (did you mean {str(named)!r}?)" if named.is_file() else ""


def _is_builtin_file_name(path: Path) -> bool:
    """``bs-3.toml`` alone: a built-in id given as a file name (no such file here)."""
    return path.parent == Path(".") and path.suffix == ".toml" and path.stem in builtin_scenarios()


def _looks_like_a_path(text: str) -> bool:
    """Whether a scenario argument is meant as a file (it ends in .toml or holds a path
    separator), not as a built-in id."""
    separators = {"/", os.sep, os.altsep or "/"}
    return text.endswith(".toml") or any(sep in text for sep in separators)


def scenario_id(id_or_path: str | Path) -> str:
    """The id a scenario runs under (its ``id`` key, else the file name), read without
    touching any FMU: what the default run folder ``runs/<id>`` is named after."""
    path = scenario_path(id_or_path)
    spec = _validate_spec(_read_toml(path), str(path))
    return _scenario_id(spec, path.stem, Source(str(path)))


def load_scenario(id_or_path: str | Path, fmu_dir: Path = DEFAULT_FMU_DIR) -> Scenario:
    """Read, validate and resolve a built-in scenario id or a scenario file.

    ``fmu_dir`` is where the built-in FMUs live (built there on first use).
    Raises :class:`ScenarioError` naming the file and the key on any problem.
    """
    path = scenario_path(id_or_path)
    spec = _validate_spec(_read_toml(path), str(path))
    src = Source(str(path))
    sid = _scenario_id(spec, path.stem, src)
    return _resolve(spec, sid, path.resolve(), path.parent, fmu_dir, src)


def scenario_from_toml(
    text: str,
    where: str = "<string>",
    base_dir: Path | None = None,
    fmu_dir: Path = DEFAULT_FMU_DIR,
) -> Scenario:
    """Like :func:`load_scenario` for scenario text (relative paths from ``base_dir``)."""
    try:
        data = loads_toml(text.removeprefix("\ufeff"))
    except NotTomlError as exc:
        raise ScenarioError(f"scenario {where}: not valid TOML: {exc}") from None
    return scenario_from_data(data, where, base_dir, fmu_dir)


def scenario_from_data(
    data: Mapping[str, Any],
    where: str = "<data>",
    base_dir: Path | None = None,
    fmu_dir: Path = DEFAULT_FMU_DIR,
) -> Scenario:
    """Like :func:`scenario_from_toml` for the parsed TOML (a study's runs: no text to
    write and parse again); ``data`` passes the same checks and is not modified."""
    spec = _validate_spec(data, where)
    src = Source(where)
    sid = _scenario_id(spec, "scenario", src)
    return _resolve(spec, sid, None, base_dir or Path.cwd(), fmu_dir, src)


def _natural_key(path: Path) -> tuple[str, int]:
    stem, _, number = path.stem.rpartition("-")
    return (stem, int(number)) if number.isdigit() else (path.stem, 0)


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        return read_toml_file(path)
    except UnreadableTomlError as exc:
        raise ScenarioError(f"scenario file {path}: {exc}") from None


def overridden_keys(names: OptionNames, options: Mapping[str, object]) -> dict[str, str]:
    """The scenario keys the options of :meth:`Scenario.with_overrides` set (``{"step":
    1e-09}``; None: not given), each to the option as ``names`` shows it: ``"coupling.step"``
    -> ``--step 1e-09`` (the command line) or ``step=1e-09`` (Python)."""
    return {
        option if option == "stop_time" else f"coupling.{option}": names.given(option, value)
        for option, value in options.items()
        if value is not None
    }


def _validate_spec(data: Mapping[str, Any], where: str, src: Source | None = None) -> ScenarioSpec:
    try:
        return ScenarioSpec.model_validate(data)
    except ValidationError as exc:
        lead = f"{', '.join(src.given.values())}: " if src is not None and src.given else ""
        raise ScenarioError(
            f"{lead}scenario file {where}: " + one_problem_per_key(exc, _key, _problem)
        ) from None


def _problem(key: str, err: ErrorDetails) -> str:
    """The problem pydantic's error ``err`` finds with the scenario file's ``key``."""
    if err["type"] == "extra_forbidden":
        hint = misplaced_top_level(key, ScenarioSpec)
        return f"unknown key {key!r}{hint}" if hint else unknown_key(key, ScenarioSpec, KEYS)
    if err["type"] == "missing":
        return f"key {key!r} is missing"
    if err["type"] == "string_pattern_mismatch":  # a name: in words, not a regex
        wanted = PATTERN_WORDS.get(str((err.get("ctx") or {}).get("pattern")))
        if wanted is None:
            return f"key {key!r} = {err.get('input')!r}: {err['msg']}"
        return f"key {key!r} = {err.get('input')!r}: expected {wanted}"
    if table_expected(err):
        problem = f"key {key!r} = {err.get('input')!r}: expected a table"
        return problem + (
            _ARRAY_OF_TABLES.get(key, "") if isinstance(err.get("input"), list) else ""
        )
    if _string_for_a_number(err):
        return f"key {key!r} = {err['input']!r}: {_number_expected(err['input'])}"
    if any(_is_union_tag(part) for part in err["loc"]):  # a start value
        return f"key {key!r} = {err.get('input')!r}: {ANY_VALUE}"
    guess = literal_guess(err)
    return f"key {key!r} = {err.get('input')!r}{guess}: {expected_words(err)}"


# what a table written as TOML's array of tables ([[connections]], as other tools write
# connections) is written as here
_ARRAY_OF_TABLES = {
    "connections": ' ([connections] with add = [{ from = "a.y", to = "b.u" }], not '
    "[[connections]]: docs/scenario-example.toml)",
    "instances": " ([instances.NAME] with fmu = ..., not [[instances]]: "
    "docs/scenario-example.toml)",
}

# pydantic's error types of a string given for a number ("60 s", "0.01")
_NOT_A_NUMBER = {"float_type", "float_parsing", "int_type", "int_parsing"}
_LEADING_NUMBER = re.compile(r"\s*([-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?)")


def _string_for_a_number(err: Any) -> bool:
    """A string given for a key that takes only a number (not a start value, which may
    also be a string)."""
    union = any(_is_union_tag(part) for part in err["loc"])
    return err["type"] in _NOT_A_NUMBER and isinstance(err.get("input"), str) and not union


def _number_expected(text: str) -> str:
    """What a string given for a number should have been: ``"60 s"``, ``"0.01"``."""
    number = _LEADING_NUMBER.match(text)
    meant = f": {number.group(1)}" if number else ""
    return f"expected a number, in SI units, without a unit or quotes{meant}"


def _key(loc: tuple[Any, ...]) -> str:
    """pydantic's error location as the scenario file's key: without the union members
    tried (:func:`_is_union_tag`) and pydantic's mark of a dict key."""
    return file_key(loc, lambda _, part: _is_union_tag(part) or part == "[key]")


def _is_union_tag(part: Any) -> bool:
    """pydantic puts the union member tried ('float', 'str', ...) in the error location."""
    return part in UNION_TAGS


# --- resolution against the FMUs' model descriptions --------------------------------------


def _scenario_id(spec: ScenarioSpec, default: str, src: Source) -> str:
    """The ``id`` key, else ``default`` (the file name), which must be a plain name too."""
    if spec.id is not None:
        return spec.id
    if re.fullmatch(_PLAIN_NAME, default) is None:
        plain = re.sub(r"[^A-Za-z0-9_.-]+", "-", default).strip(".-") or "scenario"
        raise src.error(
            "id",
            f"missing, and the file name '{default}' is not a plain name (ASCII letters "
            f"(A-Z, a-z), digits, _ . -, not starting with . or -): rename the file "
            f'{plain}.toml, or set id = "{plain}" at its top',
        )
    return default


def _resolve(
    spec: ScenarioSpec,
    scenario_id: str,
    source: Path | None,
    base_dir: Path,
    fmu_dir: Path,
    src: Source,
) -> Scenario:
    # absolute: a scenario outlives the working folder it was read in (os.chdir, %cd), and
    # its copies (with_start, with_overrides) resolve its files from these again
    base_dir, fmu_dir = base_dir.absolute(), fmu_dir.absolute()
    _check_step_count(spec, src)
    instances = {
        name: _resolve_instance(name, inst, base_dir, fmu_dir, src)
        for name, inst in spec.instances.items()
    }
    _check_once_per_process(instances, src)
    connections = _resolve_connections(spec.connections, instances, src)
    coupling = _resolve_coupling(spec, instances, connections, src)
    _check_start_not_driven(instances, connections, {c.to for c in spec.connections.add}, src)
    scenario = Scenario(
        id=scenario_id,
        summary=spec.summary,
        source=source,
        stop_time=spec.stop_time,
        coupling=coupling,
        instances=ReadOnly(instances, "scenario.instances", INSTANCES_HINT),
        connections=tuple(connections),
        record=(),
        rrd=spec.output.rrd,
        spec=spec,
        fmu_dir=fmu_dir,
        base_dir=base_dir,
        where=src.described,
    )
    record = _resolve_record(spec.output.record, scenario, src)
    _check_manoeuvre(spec.manoeuvre, record, src)
    scenario = dataclasses.replace(
        scenario, record=record, manoeuvre=spec.manoeuvre, unrecorded=_unrecorded(scenario)
    )
    scenario = dataclasses.replace(
        scenario,
        events=resolve_events(spec.events, scenario, base_dir, src),
        faults=resolve_faults(spec.faults, scenario, src),
    )
    _check_fault_columns(scenario, src)
    _check_adaptive_faults(scenario, src)
    _check_reachable_times(scenario, src)
    object.__setattr__(scenario, "loaded", True)  # frozen: set once, here
    return scenario


def _check_adaptive_faults(scenario: Scenario, src: Source) -> None:
    """Refuse, under the adaptive algorithm, a fault that counts its target's deliveries
    (one per step of the target instance): a delay of ``steps`` of them, a noise or a
    dropout drawing once per delivery. The error control chooses the steps, so the delay
    in seconds, and the draws per second, would follow the tolerance."""
    if scenario.coupling.algorithm != "adaptive":
        return
    for i, fault in enumerate(scenario.faults):
        if fault.kind not in ("delay", "noise", "dropout"):
            continue
        what = (
            f"delays by {fault.steps} of its deliveries"
            if fault.kind == "delay"
            else "draws once per delivery"
        )
        instance = fault.target.split(".", 1)[0]
        raise src.error(
            f"faults[{i}].kind",
            f"fault {fault.name!r} ({fault.kind} on {fault.target}) {what}, one per step of "
            f"{instance}, and algorithm 'adaptive' chooses the steps: its "
            f"{'delay in seconds' if fault.kind == 'delay' else 'draws per second'} would "
            "follow the tolerance; use 'gauss-seidel' or 'jacobi' with a fixed step",
        )


def _check_start_not_driven(
    instances: Mapping[str, Instance], connections: list[Connection], added: set[str], src: Source
) -> None:
    """Refuse a start value for an input a connection drives (under its name or an
    alias's): the connection would overwrite it; ``added``: the targets of
    connections.add."""

    def key(instance: str, variable: str) -> tuple[str, str, int]:
        return (instance, *alias_key(instances[instance].interface.variables[variable]))

    driven = {key(c.target_instance, c.target_variable): c for c in connections}
    for name, inst in instances.items():
        for var_name in inst.start:
            ref = f"{name}.{var_name}"
            connection = driven.get(key(name, var_name))
            if connection is None:
                continue
            target = connection.target
            hold = (
                "take its connection out of connections.add" if target in added
                else f'add "{target}" to connections.remove'
            )  # fmt: skip
            alias = "" if target == ref else f" (as {target}, one variable)"
            raise src.error(
                f"instances.{name}.start.{var_name}",
                f"input {ref} is connected from {connection.source}{alias}, so a start value "
                f"would be overwritten; {hold} to hold it instead",
            )


def _check_fault_columns(scenario: Scenario, src: Source) -> None:
    """A fault's column (``fault.<name>``) that is also a recorded variable's (of an
    instance named ``fault``): two columns of one name in results.csv, refused."""
    recorded = set(scenario.record)
    for k, fault in enumerate(scenario.faults):
        column = f"{FAULT_COLUMN_PREFIX}{fault.name}"
        if column in recorded:
            raise src.error(
                f"faults[{k}].name",
                f"{fault.name!r}: its results.csv column {column} is also the column of "
                f"instance fault's recorded variable {fault.name}; rename the fault or the "
                "instance",
            )


def _check_manoeuvre(kind: str | None, record: tuple[str, ...], src: Source) -> None:
    """A known manoeuvre whose variables the run records (it measures them at the end)."""
    if kind is None:
        return
    if kind not in KINDS:
        raise src.error(
            "manoeuvre",
            f"{kind!r} is not a manoeuvre{did_you_mean(kind, KINDS)}: expected one of "
            f"{list(KINDS)}",
        )
    try:
        manoeuvre_columns(kind, record)
    except ValueError as exc:
        raise src.error("manoeuvre", f"{exc}; record it in output.record") from None


def _check_step_count(spec: ScenarioSpec, src: Source) -> None:
    """A whole number of communication steps, and not more than :data:`MAX_STEPS`."""
    step = spec.coupling.step
    stop_steps = spec.stop_time / step
    if stop_steps > MAX_STEPS:
        # a count beyond the largest float (~1.8e308) is inf: say what it is over
        count = f"{stop_steps:.3g}" if math.isfinite(stop_steps) else "over 1e+308"
        raise src.error(
            "stop_time",
            f"{spec.stop_time!r} s is {count} communication steps of "
            f"{step!r} s (coupling.step); at most {MAX_STEPS:.0e} are run",
        )
    if round(stop_steps) < 1:
        raise src.error(
            "stop_time",
            f"{spec.stop_time!r} s is less than one communication step of {step!r} s "
            "(coupling.step): a run takes at least one step",
        )
    if abs(stop_steps - round(stop_steps)) > _STEP_TOLERANCE * max(1.0, stop_steps):
        below = math.floor(stop_steps)
        nearest = [f"{k * step:.12g} s" for k in (below, below + 1) if k >= 1]  # 0 s: no run
        raise src.error(
            "stop_time",
            f"{spec.stop_time} s is not a whole number of communication steps "
            f"(coupling.step = {step} s): the nearest "
            + (f"are {nearest[0]} and {nearest[1]}" if len(nearest) == 2 else f"is {nearest[0]}"),
        )


def _check_reachable_times(scenario: Scenario, src: Source) -> None:
    """Every event time and fault start/stop within :data:`MAX_STEPS` communication steps:
    a later one can never be reached (and t / h would overflow the step count)."""
    step = scenario.coupling.step
    times = [(f"events[{i}].time", e.time) for i, e in enumerate(scenario.events)]
    for i, fault in enumerate(scenario.faults):
        times += [(f"faults[{i}].start", fault.start), (f"faults[{i}].stop", fault.stop)]
    for key, time in times:
        if time is not None and time / step > MAX_STEPS:
            raise src.error(
                key,
                f"{time!r} s is beyond {MAX_STEPS:.0e} communication steps of {step!r} s, "
                f"the most a run takes: no run reaches it (at most {MAX_STEPS * step:.6g} s "
                "at this step)",
            )


def _check_once_per_process(instances: Mapping[str, Instance], src: Source) -> None:
    """Two instances of an FMU that declares ``canBeInstantiatedOnlyOncePerProcess="true"``
    (its code keeps global state: FMI 2.0 asks for its instances in different processes)
    are refused: a run steps every instance in one process, with one library per FMU."""
    first: dict[tuple[str, str], str] = {}  # (GUID, model identifier) -> first instance
    for name, inst in instances.items():
        md = inst.model_description
        if not md.coSimulation.canBeInstantiatedOnlyOncePerProcess:
            continue
        other = first.setdefault((md.guid, md.coSimulation.modelIdentifier), name)
        if other != name:
            raise src.error(
                f"instances.{name}.fmu",
                f"{other} and {name} are both instances of {inst.fmu_path.name}, which "
                'declares canBeInstantiatedOnlyOncePerProcess="true": FMI 2.0 allows one '
                "instance of it per process, and a run steps every instance in one; keep one",
            )


def _resolve_instance(
    name: str, spec: InstanceSpec, base_dir: Path, fmu_dir: Path, src: Source
) -> Instance:
    if spec.fmu in BUILTIN_FMUS:
        fmu_ref, fmu_path = spec.fmu, _builtin_fmu(spec.fmu, fmu_dir)
    else:
        try:
            fmu_path = (base_dir / spec.fmu).resolve()
            found = fmu_path.is_file()
        except (OSError, ValueError) as exc:  # a name too long, a NUL: never looked up
            if isinstance(exc, UnicodeError):  # a locale's encoding: said where it is caught
                raise
            raise src.error(
                f"instances.{name}.fmu",
                f"{shown(spec.fmu)}: cannot look it up: {unusable_path(exc)}",
            ) from None
        if not found:
            raise src.error(
                f"instances.{name}.fmu",
                f"{spec.fmu!r}{did_you_mean(spec.fmu, BUILTIN_FMUS)} is neither a built-in FMU "
                f"{list(BUILTIN_FMUS)} nor an existing file (looked for {fmu_path})",
            )
        fmu_ref = str(fmu_path)
    interface = _interface(fmu_path, f"instances.{name}.fmu", src)
    if interface.model_identifier is None:
        raise src.error(f"instances.{name}.fmu", f"{fmu_path}: {NOT_COSIMULATION}")
    if interface.fmi_version != "2.0":
        raise src.error(
            f"instances.{name}.fmu", f"{fmu_path} is FMI {interface.fmi_version}, expected 2.0"
        )
    variables = interface.variables
    start: dict[str, bool | int | float | str] = {}
    for var_name, value in spec.start.items():
        key = f"instances.{name}.start.{var_name}"
        var = variables.get(var_name)
        if var is None:
            raise src.error(
                key,
                f"{name} ({fmu_path.name}) has no variable {var_name!r}"
                + (did_you_mean(var_name, variables) or home_table(var_name, ScenarioSpec)),
            )
        if not var.takes_start_value:
            initial = f" (initial {var.initial!r})" if var.initial is not None else ""
            raise src.error(
                key,
                f"{name}.{var_name} is a {var.variability} {var.causality}{initial}; only "
                "parameters, inputs and variables with initial 'exact' or 'approx' (not "
                "constant) take start values",
            )
        start[var_name] = check_value(value, var, key, src)
        if isinstance(value, str) and value.endswith(FILE_SUFFIXES):
            start[var_name] = str(_existing_file(value, base_dir, key, src))
    _check_aliases(name, start, variables, src)
    if interface.model_identifier in ("AuvPlant", "AuvAutopilot") and "vehicle" in start:
        _check_vehicle(str(start["vehicle"]), f"instances.{name}.start.vehicle", src)
    if interface.model_identifier == "AuvPlant":
        vehicle = start.get("vehicle", variables["vehicle"].start)
        _check_written_over(str(vehicle), start, f"instances.{name}.start", src)
    if interface.model_identifier in ("AuvGuidance", "AuvAutopilot"):
        _check_config(interface.model_identifier, start, f"instances.{name}.start", src)
    return Instance(
        name, fmu_ref, fmu_path, ReadOnly(start, f"{name}.start", _start_hint(name)), interface,
        _debug_logging(name, spec, interface, src),
    )  # fmt: skip


def _debug_logging(
    name: str, spec: InstanceSpec, interface: FmuInterface, src: Source
) -> tuple[str, ...] | None:
    """The categories ``fmi2SetDebugLogging`` is to be called with for instance ``name``:
    None (``debug_logging`` off and no ``log_categories``), () (every category: FMI 2.0,
    2.1.5, nCategories = 0) or the ``log_categories``, each one the FMU declares in its
    ``<LogCategories>`` (an FMU declaring none takes none: ``debug_logging = true``)."""
    categories = spec.log_categories
    if categories is None:
        return () if spec.debug_logging else None
    key = f"instances.{name}.log_categories"
    if spec.debug_logging is False:
        raise src.error(key, "names categories to log, and debug_logging is false: drop one")
    problem = log_category_problem(interface, categories)
    if problem is not None:
        raise src.error(key, problem)
    return tuple(dict.fromkeys(categories))  # each once, in the order given


def _check_aliases(
    name: str, start: Mapping[str, object], variables: Mapping[str, Any], src: Source
) -> None:
    """Refuse start values for two names of one variable (aliases: one value reference of
    one type, FMI 2.0 section 2.2.7; an Enumeration shares the Integers' references): they
    would be set one after the other, the last silently winning."""
    first: dict[tuple[str, int], str] = {}
    for var_name in start:
        other = first.setdefault(alias_key(variables[var_name]), var_name)
        if other != var_name:
            raise src.error(
                f"instances.{name}.start.{var_name}",
                f"{name}.{var_name} and {name}.{other} are one variable (the same value "
                "reference): give one of them a start value",
            )


def _check_vehicle(value: str, key: str, src: Source) -> None:
    """The vehicle set of the plant or the autopilot (a built-in name, or a file resolved
    above), loaded as they load it: they would refuse a bad one only when initialised, as
    an FMU's error; here the scenario file's key is named before any FMU is loaded."""
    from plant_fmu.model.parameters import VehicleParameterError, load_vehicle

    try:
        load_vehicle(value)
    except VehicleParameterError as exc:
        raise src.error(key, str(exc)) from None


def plant_vehicle(vehicle: str, start: Mapping[str, Any]) -> VehicleParameters:
    """The parameter set a plant (``AuvPlant``) runs: its ``vehicle`` set with the
    physical parameters among the ``start`` values written over, validated as a whole as
    the plant validates it (:meth:`VehicleParameters.replace`). Raises
    :class:`~plant_fmu.model.parameters.VehicleParameterError`."""
    from plant_fmu.model.parameters import load_vehicle

    base = load_vehicle(vehicle)
    overrides = {key: start[key] for key in _written_over(base, start)}
    return base.replace(**overrides) if overrides else base


def _written_over(base: VehicleParameters, start: Mapping[str, Any]) -> list[str]:
    """The physical parameters of ``base`` that ``start`` gives (not its name and
    description, which are no physics and no start values)."""
    fields = set(base.as_dict()) - {"name", "description"}
    return [key for key in start if key in fields]


def _check_written_over(vehicle: str, start: Mapping[str, Any], key: str, src: Source) -> None:
    """The plant's physical parameters written over its vehicle set, valid each on its
    own (its range) but maybe not together (a mass ``m`` below the moving mass's ``m_v``):
    checked with the set here, naming the key, where the plant refused them only once
    initialised (the run's first step)."""
    from plant_fmu.model.parameters import VehicleParameterError, load_vehicle

    try:
        plant_vehicle(vehicle, start)
    except VehicleParameterError as exc:
        base = load_vehicle(vehicle)  # loaded above: only the written-over values failed
        written = _written_over(base, start)
        reason = str(exc).removeprefix(f"vehicle {f'{base.name} (modified)'!r}: ")
        where = f"{key}.{written[0]}" if len(written) == 1 else key
        raise src.error(
            where, f"vehicle {base.name!r} with {', '.join(written)} written over: {reason}"
        ) from None


def _check_config(model: str, start: Mapping[str, Any], key: str, src: Source) -> None:
    """The parameters of a guidance (``model`` AuvGuidance: its waypoints, lookahead, ...)
    or an autopilot (AuvAutopilot: design speed, gains, ...), checked as the FMU checks
    them when initialised (:class:`controller_fmu.los_guidance.GuidanceConfig`,
    :class:`controller_fmu.autopilot.AutopilotConfig`), where a value within its FMI range
    (``design_speed = 0``) failed the run at t = 0 naming neither the file nor the key:
    here the key is named before any FMU is loaded, each value on its own first, then
    together."""
    from controller_fmu.autopilot_config import AutopilotConfig
    from controller_fmu.los_guidance import GuidanceConfig

    config = GuidanceConfig if model == "AuvGuidance" else AutopilotConfig

    def check(values: Mapping[str, Any], where: str) -> None:
        try:
            config.build(**values)
        except config.error_type as exc:
            raise src.error(where, str(exc)) from None

    given = {name: value for name, value in start.items() if name in config.field_info()}
    for name, value in given.items():
        check({name: value}, f"{key}.{name}")
    check(given, key)


def _existing_file(value: str, base_dir: Path, key: str, src: Source) -> Path:
    """A file named in a start value, relative to the scenario's folder; must exist."""
    path = (base_dir / value).resolve()
    if not path.is_file():
        raise src.error(key, f"{value!r} names no file (looked for {path})")
    return path


def _resolve_coupling(
    spec: ScenarioSpec,
    instances: Mapping[str, Instance],
    connections: list[Connection],
    src: Source,
) -> Coupling:
    """The coupling as written, its defaults filled in (docs/coupling.md): the order the
    connections imply, the extrapolation, the adaptive algorithm's tolerance and longest
    step; an algebraic loop is refused, naming it."""
    c, names = spec.coupling, list(instances)
    passes = {name: feedthrough(inst.model_description) for name, inst in instances.items()}
    pairs = [(conn.source, conn.target) for conn in connections]
    loop = algebraic_loop(passes, pairs)
    if loop is not None:
        raise src.error(
            "connections",
            f"algebraic loop {' -> '.join(loop)}: every output in it depends directly on the "
            "input before it (the FMUs' ModelStructure), so no order gives each instance its "
            "inputs at the same point; remove one of its connections",
        )
    order = tuple(c.order) if c.order is not None else connection_order(names, passes, pairs)
    if sorted(order) != sorted(names):
        unknown = next((name for name in order if name not in names), None)
        stray = "" if unknown is None else f": no instance {unknown!r}"
        raise src.error(
            "coupling.order",
            f"{list(order)} must name every instance {names} once{stray}"
            + ("" if unknown is None else did_you_mean(unknown, names)),
        )
    for name in c.step_multiples:
        if name not in names:
            raise src.error(
                f"coupling.step_multiples.{name}",
                f"no instance {name!r}{did_you_mean(name, names)} in {names}",
            )
    multiples = {name: c.step_multiples.get(name, 1) for name in names}
    hint = "a scenario file's [coupling.step_multiples] (then cosim.load_scenario it)"
    adaptive = c.algorithm == "adaptive"
    for key in ("tolerance", "max_step", "error_estimate"):
        if getattr(c, key) is not None and not adaptive:
            raise src.error(f"coupling.{key}", f"applies to algorithm = 'adaptive' only, "
                            f"not {c.algorithm!r}")  # fmt: skip
    if c.extrapolation is not None:
        extrapolation = c.extrapolation
    elif "algorithm" in c.model_fields_set and not adaptive:
        extrapolation = "none"  # a file naming its algorithm keeps the held values
    else:
        extrapolation = DEFAULT_EXTRAPOLATION
    coupling = Coupling(
        step=c.step,
        algorithm=c.algorithm,
        order=order,
        step_multiples=ReadOnly(multiples, "scenario.coupling.step_multiples", hint),
        extrapolation=extrapolation,
        tolerance=(c.tolerance or DEFAULT_TOLERANCE) if adaptive else None,
        max_step=(c.max_step or DEFAULT_MAX_STEPS * c.step) if adaptive else None,
        error_estimate=(c.error_estimate or DEFAULT_ERROR_ESTIMATE) if adaptive else None,
    )
    _check_step_sizes(spec, coupling, instances, src)
    return coupling


def _check_step_sizes(
    spec: ScenarioSpec, coupling: Coupling, instances: Mapping[str, Instance], src: Source
) -> None:
    """What the FMUs' co-simulation capabilities allow: an FMU that cannot change its
    step (``canHandleVariableCommunicationStepSize="false"``) steps k h to the stop time
    without a shorter last step, and never under the adaptive algorithm, which also rolls
    every FMU back (``canGetAndSetFMUstate``)."""
    for name, inst in instances.items():
        cs = inst.model_description.coSimulation
        k = coupling.step_multiples[name]
        if coupling.algorithm == "adaptive":
            if coupling.max_step is not None and coupling.max_step < coupling.step:
                raise src.error(
                    "coupling.max_step",
                    f"{coupling.max_step!r} s is shorter than coupling.step = {coupling.step!r} s",
                )
            for flag in ("canHandleVariableCommunicationStepSize", "canGetAndSetFMUstate"):
                if not getattr(cs, flag):
                    raise src.error(
                        "coupling.algorithm",
                        f"'adaptive' changes every step and rolls rejected steps back, but "
                        f'{name} ({inst.fmu_path.name}) declares {flag}="false": use '
                        "'gauss-seidel' or 'jacobi' with a fixed step",
                    )
            continue
        _check_sample_period(name, inst, k * coupling.step, src)
        steps = spec.stop_time / (k * coupling.step)
        whole = abs(steps - round(steps)) <= _STEP_TOLERANCE * max(1.0, steps)
        if not cs.canHandleVariableCommunicationStepSize and not whole:
            raise src.error(
                "stop_time",
                f"{spec.stop_time!r} s is not a whole number of {name}'s steps of "
                f"{k * coupling.step!r} s, and {name} ({inst.fmu_path.name}) declares "
                'canHandleVariableCommunicationStepSize="false": its last step cannot be '
                "shortened; choose a stop time that is a multiple of its step",
            )


def sample_period(inst: Instance) -> float:
    """The period (s) at which ``inst`` samples at times of its own, 0.0 for none: our
    autopilot's ``sample_period`` (its digital laws), whatever its value type in the file.
    Our autopilot's only: another FMU's value of that name means what that FMU makes of
    it (a sampling period or not), so a run neither checks it nor steps to it."""
    if inst.interface.model_identifier != "AuvAutopilot":
        return 0.0
    period = inst.start.get("sample_period", 0.0)
    return float(period) if isinstance(period, float | int) and period > 0.0 else 0.0


def _check_sample_period(name: str, inst: Instance, step: float, src: Source) -> None:
    """A digital controller's ``sample_period`` (s; the autopilot's) longer than its step
    ``step`` (s, k h) must be a whole number of those steps: it samples at the first doStep
    at or after each multiple of its period, so another period takes some samples up to a
    step late, without a word (a period the step is longer than samples at every step,
    which the autopilot warns of itself). The adaptive algorithm ends a step on each
    sample instead (:func:`cosim.engine.adaptive.sample_periods`)."""
    period = sample_period(inst)
    if not period > step:
        return
    steps = period / step
    if abs(steps - round(steps)) <= _STEP_TOLERANCE * steps:
        return
    raise src.error(
        f"instances.{name}.start.sample_period",
        f"{period!r} s is not a whole number of {name}'s steps of {step!r} s (coupling.step "
        "x its step_multiples): it samples at the first step at or after each multiple of "
        "its period, so some samples would be up to a step late; choose a sample_period "
        f"that is a multiple of {step!r} s, or a step that divides {period!r} s",
    )


def _resolve_connections(
    spec: ConnectionsSpec, instances: Mapping[str, Instance], src: Source
) -> list[Connection]:
    settled = {*spec.remove, *(conn.to for conn in spec.add)}  # no same-name source asked
    by_target = _same_name_connections(instances, settled, src) if spec.same_names else {}
    for i, ref in enumerate(spec.remove):
        key = f"connections.remove[{i}]"
        if ref in spec.remove[:i]:
            raise src.error(key, f"{ref!r} is listed twice")
        _, var = split_ref(ref, instances, key, src)
        if var.causality != "input":
            what = with_article(var.causality)
            raise src.error(key, f"{ref!r} is {what}; remove names an input to leave unconnected")
        by_target.pop(ref, None)
    added: dict[str, int] = {}  # target -> index in connections.add
    for i, conn in enumerate(spec.add):
        key = f"connections.add[{i}]"
        src_inst, source = split_ref(conn.from_, instances, f"{key}.from", src)
        tgt_inst, target = split_ref(conn.to, instances, f"{key}.to", src)
        if source.causality != "output":
            raise src.error(
                f"{key}.from", f"{conn.from_!r} is {with_article(source.causality)}, not an output"
            )
        if target.causality != "input":
            raise src.error(
                f"{key}.to", f"{conn.to!r} is {with_article(target.causality)}, not an input"
            )
        if src_inst == tgt_inst:
            raise src.error(key, f"{conn.from_!r} -> {conn.to!r} connects an instance to itself")
        if not _connectable(source.type, target.type):
            raise src.error(key, _type_mismatch(source.type, target.type))
        if conn.to in added:
            raise src.error(
                f"{key}.to",
                f"{conn.to!r} is driven twice: by connections.add[{added[conn.to]}] "
                f"({by_target[conn.to].source}) and here ({conn.from_}); an input has one source",
            )
        added[conn.to] = i
        by_target[conn.to] = Connection(conn.from_, conn.to)
    _check_aliased_targets(by_target, added, instances, src)
    _check_units(by_target, added, instances, src)
    return sorted(by_target.values(), key=lambda c: (c.target_instance, c.target_variable))


def _check_aliased_targets(
    by_target: Mapping[str, Connection],
    added: Mapping[str, int],
    instances: Mapping[str, Instance],
    src: Source,
) -> None:
    """Refuse two connections into two names of one input (aliases): both would set it,
    the last silently winning; the refusal names the key that made the second."""
    first: dict[tuple[str, str, int], str] = {}
    for target, connection in by_target.items():
        inst = instances[connection.target_instance]
        var = inst.interface.variables[connection.target_variable]
        other = first.setdefault((inst.name, *alias_key(var)), target)
        if other == target:
            continue
        key = (
            f"connections.add[{added[target]}].to" if target in added else "connections.same_names"
        )
        raise src.error(
            key,
            f"{target!r} and {other!r} are one variable (the same value reference), driven by "
            f"{by_target[other].source} and {connection.source}; an input has one source",
        )


def _check_units(
    by_target: Mapping[str, Connection],
    added: Mapping[str, int],
    instances: Mapping[str, Instance],
    src: Source,
) -> None:
    """Every connection joins variables of one unit (:mod:`cosim.scenario.connection_units`);
    the refusal names the key that made it (``added``: target -> index in connections.add)."""
    for target, connection in by_target.items():
        source, into = instances[connection.source_instance], instances[connection.target_instance]
        difference = unit_difference(
            (
                connection.source,
                source.model_description,
                source.variable(connection.source_variable),
            ),
            (target, into.model_description, into.variable(connection.target_variable)),
        )
        if difference is None:
            continue
        if target in added:
            raise src.error(f"connections.add[{added[target]}]", difference)
        raise src.error(
            "connections.same_names",
            f'{difference}; add "{target}" to connections.remove to leave it unconnected',
        )


def _same_name_connections(
    instances: Mapping[str, Instance], settled: Collection[str], src: Source
) -> dict[str, Connection]:
    """Every input driven by the one output of the same name in another instance; an input
    with several is refused unless ``settled`` names it (connections.add drives it or
    connections.remove leaves it unconnected: two vehicles' autopilots and plants)."""
    by_target: dict[str, Connection] = {}
    for target, target_inst in instances.items():
        for var in target_inst.variables("input"):
            if f"{target}.{var.name}" in settled:
                continue
            sources = [
                name
                for name, inst in instances.items()
                if name != target
                and (out := inst.interface.variables.get(var.name)) is not None
                and out.causality == "output"
                and out.type == var.type
                and _connectable(out.type, var.type)
            ]
            if len(sources) > 1:
                raise src.error(
                    "connections.same_names",
                    f"input {target}.{var.name} has several same-named outputs {sources}: "
                    "connect it in connections.add, leave it unconnected in "
                    "connections.remove, or set same_names = false and list every connection",
                )
            if sources:
                tgt = f"{target}.{var.name}"
                by_target[tgt] = Connection(f"{sources[0]}.{var.name}", tgt)
    return by_target


def _connectable(source: str, target: str) -> bool:
    """An output of FMI type ``source`` can drive an input of type ``target``: the same
    numeric type (an Enumeration is an Integer on the wire); not a String."""
    integer = ("Integer", "Enumeration")
    return source != "String" and (source == target or (source in integer and target in integer))


def _type_mismatch(source: str, target: str) -> str:
    if "String" in (source, target):
        return (
            f"{source} -> {target}: String values are not exchanged (the master exchanges "
            "Real, Integer, Enumeration and Boolean values)"
        )
    return f"{source} -> {target}: an output drives an input of its own type only"


RECORDABLE = ("Real", "Integer", "Enumeration", "Boolean")  # results.csv holds numbers


def _resolve_record(record: list[str] | None, scenario: Scenario, src: Source) -> tuple[str, ...]:
    """The recorded columns: ``record`` checked, or every output and unconnected input
    whose type results.csv can hold (Booleans as 0 and 1)."""
    if record is None:
        columns = []
        for name, inst in scenario.instances.items():
            columns += [
                f"{name}.{v.name}" for v in inst.variables("output") if v.type in RECORDABLE
            ]
            unconnected = set(scenario.unconnected_inputs(name))
            columns += [
                f"{name}.{v.name}"
                for v in inst.variables("input")
                if v.name in unconnected and v.type in RECORDABLE
            ]
        return tuple(columns)
    for i, ref in enumerate(record):
        _, var = split_ref(ref, scenario.instances, f"output.record[{i}]", src)
        if var.type not in RECORDABLE:
            raise src.error(
                f"output.record[{i}]",
                f"{ref!r} is {var.type}: results.csv holds numbers, so "
                f"{', '.join(RECORDABLE)} variables are recorded, not {var.type} ones",
            )
        if ref in record[:i]:
            raise src.error(
                f"output.record[{i}]", f"{ref!r} is listed twice: at [{record.index(ref)}] and here"
            )
    return tuple(record)


def _unrecorded(scenario: Scenario) -> tuple[str, ...]:
    """The outputs a scenario without ``output.record`` leaves out (String ones)."""
    if scenario.spec.output.record is not None:
        return ()
    return tuple(
        f"{name}.{v.name}"
        for name, inst in scenario.instances.items()
        for v in inst.variables("output")
        if v.type not in RECORDABLE
    )


# --- FMU look-up (no FMU is loaded here) -------------------------------------------------


def _builtin_fmu(name: str, fmu_dir: Path) -> Path:
    """A built-in FMU in ``fmu_dir``, built there if missing or out of date (portable if
    the one there was)."""
    from cosim.fmus.build import build_fmu

    return build_fmu(name, fmu_dir, portable=None)


def _interface(path: Path, key: str, src: Source) -> FmuInterface:
    """The FMU's interface (:func:`cosim.fmus.interface.read_interface`, cached); a file
    that is no FMU (a vehicle set given as one, say) refused naming ``key``."""
    try:
        return read_interface(path)
    except FmuInterfaceError as exc:
        raise src.error(key, str(exc)) from None


def debug_logs(value: object, keyword: str, error: type[CosimError]) -> dict[str, tuple[str, ...]]:
    """``value`` as {instance: (log categories, ...)} (``()``: every category), the form
    :meth:`Scenario.with_debug_logging` and ``cosim.run``'s and ``cosim.sweep``'s
    ``fmu_log`` take; else ``error``, one line naming ``keyword``. The instances and
    categories are checked against the scenario later."""
    if not isinstance(value, Mapping):
        raise error(f"{keyword}={shown(value)}: expected a mapping {{instance: [log categories]}}")
    for name, categories in value.items():
        if not isinstance(name, str) or not name:
            raise error(
                f"{keyword}={shown(value)}: expected instance names as keys, not {shown(name)}"
            )
        if not isinstance(categories, list | tuple) or not all(
            isinstance(c, str) and c for c in categories
        ):
            raise error(f"{keyword}={shown(value)}: expected a list of log categories for "
                        f"{name!r} ([] for every one)")  # fmt: skip
    return {name: tuple(categories) for name, categories in value.items()}
