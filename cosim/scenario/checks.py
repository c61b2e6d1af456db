"""What every part of a scenario file is checked with: the error, the strict pydantic base,
where the file comes from, and the look-up and type check of one ``<instance>.<variable>``.

Shared by :mod:`cosim.scenario.spec` (instances, connections, records) and
:mod:`cosim.scenario.timeline_spec` (events and faults), so that both report a problem the same
way: one line naming the file, the key, the bad value and what was expected; a study file
(:mod:`cosim.study.spec`) words pydantic's errors with the same helpers
(:func:`one_problem_per_key`, :func:`file_key`, :func:`unknown_key`).
"""

from __future__ import annotations

import dataclasses
import math
import re
import sys
import types
import typing
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, NoReturn

from pydantic import BaseModel, ConfigDict, ValidationError
from pydantic_core import ErrorDetails

from cosim.errors import CosimError, counted, did_you_mean, shown

FMI_INTEGER_RANGE = (-(2**31), 2**31 - 1)  # fmi2Integer is a C int (32 bits)


class ScenarioError(CosimError):
    """A scenario that cannot run: the message names the file and the key."""


class Strict(BaseModel):
    """The base of every part of a scenario file: unknown keys are errors, nothing coerced."""

    # strict: "2.0" is not a number and 2.0 not an integer (an int is a valid float)
    model_config: ClassVar[ConfigDict] = ConfigDict(extra="forbid", frozen=True, strict=True)


def _refused(method: str) -> Callable[..., NoReturn]:
    """A :class:`ReadOnly` method that would change it: refused, naming ``method``."""

    def refuse(self: ReadOnly, *args: Any, **kwargs: Any) -> NoReturn:
        raise self._refusal(f"{self._name}.{method}(...)")

    return refuse


class ReadOnly(Mapping[str, Any]):
    """A mapping of a resolved scenario (its ``instances``, an instance's ``start``, its
    coupling's ``step_multiples``, an event's ``set``): read-only, since an edit would
    bypass the scenario's checks and be lost on the next override. ``hint`` says what to
    call instead; picklable and copyable."""

    __slots__ = ("_hint", "_items", "_name")

    def __init__(self, items: Mapping[str, Any], name: str, hint: str) -> None:
        self._items = dict(items)
        self._name = name  # as an edit's refusal names the mapping: "plant.start"
        self._hint = hint

    def __getitem__(self, key: str) -> Any:
        return self._items[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return repr(self._items)

    def __setitem__(self, key: str, value: Any) -> None:
        raise self._refusal(f"{self._name}[{key!r}] = {value!r}")

    def __delitem__(self, key: str) -> None:
        raise self._refusal(f"del {self._name}[{key!r}]")

    def _refusal(self, edit: str) -> TypeError:
        return TypeError(f"{edit}: a loaded scenario is read-only; expected {self._hint}")

    update = _refused("update")
    pop = _refused("pop")
    popitem = _refused("popitem")
    setdefault = _refused("setdefault")
    clear = _refused("clear")


def field_names(model: type[BaseModel]) -> set[str]:
    """Every key a file validated by ``model`` may hold, at any depth: the names of its
    fields and of the fields of the models they hold (in lists, dicts and unions too), for
    a suggestion to a mistyped one."""
    names: set[str] = set()
    pending: list[Any] = [model]
    seen: set[type[BaseModel]] = set()
    while pending:
        kind = pending.pop()
        if isinstance(kind, type) and issubclass(kind, BaseModel):
            if kind not in seen:
                seen.add(kind)
                names.update(kind.model_fields)
                pending.extend(field.annotation for field in kind.model_fields.values())
        else:
            pending.extend(typing.get_args(kind))
    return names


def misplaced_top_level(key: str, model: type[BaseModel]) -> str:
    """A hint, in parentheses with a leading space, for a key of a table (``key`` as a
    refusal names it: ``faults[0].stop_time``) that is a top-level key of ``model``'s file:
    TOML reads a key written below a ``[table]`` or ``[[table]]`` header into that table,
    so ``stop_time = 60.0`` appended to a file ends up in its last one. ``""`` otherwise."""
    table, _, name = key.rpartition(".")
    if not table or name not in model.model_fields:
        return ""
    return (
        " (a top-level key: TOML puts every key below a [table] or [[table]] header into it; "
        f"write {name} before the first header)"
    )


def unknown_key(
    key: str,
    root: type[BaseModel],
    everywhere: Iterable[str],
    takes: Mapping[type[BaseModel], list[str]] | None = None,
) -> str:
    """The problem of ``key`` (``coupling.method``, ``faults[0].kind``), which no table of
    ``root``'s file takes: the key of its own table it is closest to (among every key of
    the file, ``everywhere``, "did you mean 'step'" for ``stop`` came from another table),
    else what that table takes. ``takes``: a table's keys in words, where they are not its
    field names (a study's ``[random]`` takes factors as dotted keys)."""
    table, _, name = key.rpartition(".")
    model = table_model(root, table)
    if model is None:  # a key below a value that is no table of fields
        return f"unknown key {key!r}{did_you_mean(name, everywhere)}"
    names = (takes or {}).get(model) or sorted(model.model_fields)
    hint = did_you_mean(name, [n for n in names if " " not in n]) or home_table(name, root)
    if hint:
        return f"unknown key {key!r}{hint}"
    listed = ", ".join(names[:-1]) + " and " + names[-1] if len(names) > 1 else names[0]
    where = "the file's top level" if not table else table if table.endswith("]") else f"[{table}]"
    return f"unknown key {key!r}: {where} takes {listed}{_free_table_hint(model, table)}"


def home_table(name: str, root: type[BaseModel]) -> str:
    """A hint, in parentheses with a leading space, naming the one table of ``root``'s file
    whose key ``name`` is (``step``: ``[coupling]``), for a key written in another table;
    ``""`` when no table or several take it. The items of a list of tables (``[[faults]]``)
    are left out: their keys are common words (``stop``, ``name``, ``value``) more often
    meant as something else than as a fault's."""
    homes = [
        table
        for table, model in tables(root)
        if name in model.model_fields and not table.startswith("[[")
    ]
    if len(homes) != 1:
        return ""
    return f" (a key of {homes[0]}: write it below the {homes[0]} header)"


def tables(root: type[BaseModel], path: str = "") -> Iterator[tuple[str, type[BaseModel]]]:
    """(header, model) of every table below ``root``'s top level, as a file writes its
    header: ``[coupling]``, ``[instances.<name>]`` (an entry of a dict), ``[[faults]]`` (an
    item of a list)."""
    for field_name, field in root.model_fields.items():
        kind = _unwrapped(field.annotation)
        origin, dotted = typing.get_origin(kind), f"{path}.{field_name}" if path else field_name
        inner = _one_model(typing.get_args(kind)[-1]) if origin in (dict, list) else None
        model = _one_model(kind)
        if model is not None:
            yield f"[{dotted}]", model
            yield from tables(model, dotted)
        elif inner is not None and origin is dict:
            yield f"[{dotted}.<name>]", inner
            yield from tables(inner, f"{dotted}.<name>")
        elif inner is not None:
            yield f"[[{dotted}]]", inner
            yield from tables(inner, dotted)


def _free_table_hint(model: type[BaseModel], table: str) -> str:
    """A hint naming the subtable of ``model`` whose keys are free names (an instance's
    ``start``: its FMU's variables), where an unknown key may have been meant to go."""
    free = [
        name
        for name, field in model.model_fields.items()
        if typing.get_origin(_unwrapped(field.annotation)) is dict
        and _one_model(typing.get_args(_unwrapped(field.annotation))[-1]) is None
    ]
    if len(free) != 1 or not table or table.endswith("]"):
        return ""
    return f" (a {free[0]} value goes below [{table}.{free[0]}])"


def table_expected(err: Mapping[str, Any]) -> bool:
    """Whether the pydantic error ``err`` refuses a value given where the file takes a
    table (``coupling = 0.01``), which pydantic says as "Input should be a valid dictionary
    or instance of CouplingSpec": a class of the code and a Python word for a TOML table."""
    return err.get("type") in {"model_type", "dict_type"}


def literal_guess(err: Mapping[str, Any]) -> str:
    """`` (did you mean 'gauss-seidel'?)`` for a pydantic error ``err`` refusing a string
    that is not one of a key's choices (``algorithm = "gauss_seidel"``), else ``""``."""
    value = err.get("input")
    if err.get("type") != "literal_error" or not isinstance(value, str):
        return ""
    return did_you_mean(value, re.findall(r"'([^']*)'", str(err["ctx"]["expected"])))


# pydantic's error types, what each expects in the words of every refusal
_EXPECTED = {
    "string_type": "a text",
    "int_type": "an integer",
    "int_from_float": "an integer",
    "int_parsing": "an integer",
    "float_type": "a number",
    "float_parsing": "a number",
    "finite_number": "a finite number",
    "bool_type": "true or false",
    "bool_parsing": "true or false",
    "list_type": "a list",
}
# a bound's error type: its key in the error's context, and the words naming it
_BOUNDS = {
    "greater_than": ("gt", "greater than"),
    "greater_than_equal": ("ge", "greater than or equal to"),
    "less_than": ("lt", "less than"),
    "less_than_equal": ("le", "less than or equal to"),
}


def expected_words(err: Mapping[str, Any]) -> str:
    """What the pydantic error ``err`` expects, as every refusal says it ("expected a text",
    "expected at least 1 item"), rather than pydantic's "Input should be a valid string";
    pydantic's message for an error type not named here."""
    kind, ctx = err.get("type"), err.get("ctx") or {}
    if kind in _EXPECTED:
        return f"expected {_EXPECTED[kind]}"
    if kind in _BOUNDS:
        name, words = _BOUNDS[kind]
        bound = ctx[name]
        return f"expected a number {words} {f'{bound:g}' if isinstance(bound, float) else bound}"
    if kind == "too_short":
        return f"expected at least {counted(ctx['min_length'], 'item')}"
    if kind == "too_long":
        return f"expected at most {counted(ctx['max_length'], 'item')}"
    if kind == "string_too_short":
        return f"expected a text of at least {counted(ctx['min_length'], 'character')}"
    if kind == "literal_error":
        return f"expected {ctx['expected']}"
    return str(err["msg"])


# pydantic puts the member of a union it tried ("float", "str", ...) in an error's location
UNION_TAGS = frozenset({"bool", "int", "float", "str"})
ANY_VALUE = "expected a number, an integer, true/false or a string"  # a start value's types


def file_key(loc: tuple[Any, ...], dropped: Callable[[int, Any], bool]) -> str:
    """pydantic's error location ``loc`` as the file's key, in the notation of every
    refusal: ``faults[0].std`` (a list index in brackets), without the parts ``dropped``
    (its index in ``loc``, the part) says are no keys of the file (a union member tried)."""
    key = ""
    for i, part in enumerate(loc):
        if isinstance(part, int):
            key += f"[{part}]"
        elif not dropped(i, part):
            key += f".{part}" if key else str(part)
    return key


def one_problem_per_key(
    exc: ValidationError,
    key_of: Callable[[tuple[Any, ...]], str],
    problem_of: Callable[[str, ErrorDetails], str],
) -> str:
    """pydantic's errors of one file in one line: the problem (``problem_of`` the key and
    the error) of each key (``key_of`` an error's location) that has one, the first one a
    key has (pydantic tries each member of a union and refuses the value once per member),
    joined by ``"; "``."""
    problems: dict[str, str] = {}
    for err in exc.errors():
        key = key_of(err["loc"])
        if key not in problems:
            problems[key] = problem_of(key, err)
    return "; ".join(problems.values())


def table_model(root: type[BaseModel], table: str) -> type[BaseModel] | None:
    """The model of the table at the dotted path ``table`` of ``root``'s file (``""``: the
    top level; ``instances.plant``: an entry of a dict of models; ``faults[0]``: an item of
    a list), or None when the path leads elsewhere or to a union of several models."""
    kind: Any = root
    parts = [p for p in re.split(r"\.|(?=\[)", table) if p] if table else []
    while parts:
        model = _one_model(kind)
        part = parts.pop(0)
        if model is None or part.startswith("[") or part not in model.model_fields:
            return None
        kind = model.model_fields[part].annotation
        origin = typing.get_origin(_unwrapped(kind))
        if origin in (dict, list) and parts:  # the next part names an entry or an item
            parts.pop(0)
            kind = typing.get_args(_unwrapped(kind))[-1]
    return _one_model(kind)


def _unwrapped(kind: Any) -> Any:
    """``kind`` without ``Annotated[...]`` and ``| None``."""
    while typing.get_origin(kind) is typing.Annotated:
        kind = typing.get_args(kind)[0]
    members = [m for m in typing.get_args(kind) if m is not type(None)]
    if typing.get_origin(kind) in (typing.Union, types.UnionType) and len(members) == 1:
        return _unwrapped(members[0])
    return kind


def _one_model(kind: Any) -> type[BaseModel] | None:
    """The model ``kind`` is (unwrapped), or None."""
    kind = _unwrapped(kind)
    return kind if isinstance(kind, type) and issubclass(kind, BaseModel) else None


@dataclass(frozen=True)
class Source:
    """Where a scenario comes from: every problem found resolving it names it."""

    where: str  # the file, or a description of the text
    # the keys a caller's options override, each as the caller gave it ("stop_time" ->
    # "--stop-time 1e+12"): a problem with the scenario they make names them first
    given: Mapping[str, str] = dataclasses.field(default_factory=dict)

    @property
    def described(self) -> str:
        """The scenario as later refusals name it: ``where``, with the options given."""
        return f"{self.where} (with {', '.join(self.given.values())})" if self.given else self.where

    def error(self, key: str, problem: str, causes: Collection[str] | None = None) -> ScenarioError:
        """The error for ``key`` of this scenario (raise it): an overridden key named by
        the option that set it, any other key after the options that made it a problem:
        those setting one of ``causes`` (the keys the problem depends on), or every option
        given for None."""
        if key in self.given:
            return ScenarioError(f"{self.given[key]}: {problem}")
        shown_options = [
            option for given, option in self.given.items() if causes is None or given in causes
        ]
        lead = f"{', '.join(shown_options)}: " if shown_options else ""
        return ScenarioError(f"{lead}scenario file {self.where}: key {key!r}: {problem}")


def check_value(value: Any, var: Any, key: str, src: Source) -> bool | int | float | str:
    """``value`` as a value of ``var`` (an FMU interface variable): its FMI type, finite,
    within its range, an Enumeration one of its items; the name of one of its named values
    (an Enumeration's items) stands for that value."""
    if isinstance(value, str) and var.names:
        if value not in var.names:
            guess = did_you_mean(value, var.names)
            raise src.error(
                key, f"{value!r} is not a {var.name}{guess}: expected one of {named_values(var)}"
            )
        value = var.names[value]
    expected = {"Real": "a number", "Integer": "an integer", "Enumeration": "an integer",
                "Boolean": "true or false", "String": "a string"}[var.type]  # fmt: skip
    ok = {
        "Real": isinstance(value, int | float) and not isinstance(value, bool),
        "Integer": isinstance(value, int) and not isinstance(value, bool),
        "Enumeration": isinstance(value, int) and not isinstance(value, bool),
        "Boolean": isinstance(value, bool),
        "String": isinstance(value, str),
    }[var.type]
    if not ok:  # "0.5 kn", "270 deg": the unit the number is to be given in is named
        unit = getattr(var, "unit", None) if var.type in ("Real", "Integer") else None
        of = f": expected {expected} of {unit}" if unit and unit != "1" else ""
        raise src.error(key, f"{shown(value)} is not {expected} ({var.name} is {var.type}){of}")
    if var.type == "Real":
        if isinstance(value, int) and abs(value) > sys.float_info.max:  # float() would raise
            raise src.error(key, f"{shown(value)} is not a finite number")
        value = float(value)
        if not math.isfinite(value):
            raise src.error(key, f"{value!r} is not a finite number")
        low, high = real_range(var)
        if not low <= value <= high:  # FMI 2.0: the environment keeps to min and max
            raise src.error(
                key, f"{value!r} is outside {range_text(low, high, var.name)}{sign_note(var)}"
            )
    if var.type == "Enumeration" and var.names and value not in var.names.values():
        raise src.error(
            key, f"{value} is not an item of {var.name}: expected one of {named_values(var)}"
        )
    if var.type in ("Integer", "Enumeration"):
        low, high = integer_range(var)
        if not low <= value <= high:
            raise src.error(key, f"{shown(value)} is outside {range_text(low, high, var.name)}")
    return value


def named_values(var: Any) -> str:
    """``'name' (number), ...``: the named values of ``var``, for a refusal."""
    return ", ".join(f"{name!r} ({number})" for name, number in var.names.items())


def range_text(low: float, high: float, name: str) -> str:
    """``[low, high], the range <name> takes``: how every refusal of a value names a range."""
    return f"[{low}, {high}], the range {name} takes"


def sign_note(var: Any) -> str:
    """`` (depths are down positive, 0 m at the surface)`` for a variable whose description
    says it counts down positive (a depth: a negative value is above the surface), else
    ``""``: what a refusal of its range adds, since the range alone does not say it."""
    return DEPTH_NOTE if DOWN_POSITIVE in (var.description or "") else ""


DOWN_POSITIVE = "down positive"  # how an FMU variable's description says it counts down
DEPTH_NOTE = " (depths are down positive, 0 m at the surface)"


def real_range(var: Any) -> tuple[float, float]:
    """The variable's declared ``min`` and ``max`` (-inf, inf where it declares none)."""
    low = -math.inf if var.min is None else float(var.min)
    high = math.inf if var.max is None else float(var.max)
    return low, high


def integer_range(var: Any) -> tuple[int, int]:
    """The FMI 32-bit range, narrowed by the variable's declared ``min``/``max``."""
    low, high = FMI_INTEGER_RANGE
    if var.min is not None:
        low = max(low, var.min)
    if var.max is not None:
        high = min(high, var.max)
    return low, high


def split_ref(ref: str, instances: Mapping[str, Any], key: str, src: Source) -> tuple[str, Any]:
    """``"<instance>.<variable>"`` -> (instance name, its interface variable); ``instances``
    maps names to resolved instances (``.interface``, ``.fmu_path``)."""
    instance, _, variable = ref.partition(".")
    if instance not in instances or not variable:
        raise src.error(
            key,
            f"{ref!r} is not <instance>.<variable> with an instance in {list(instances)}"
            + did_you_mean(instance, instances),
        )
    var = instances[instance].interface.variables.get(variable)
    if var is None:
        fmu = instances[instance].fmu_path.name
        raise src.error(
            key,
            f"{instance} ({fmu}) has no variable {variable!r}"
            + did_you_mean(variable, instances[instance].interface.variables),
        )
    return instance, var


def alias_key(var: Any) -> tuple[str, int]:
    """(FMI type, value reference) of ``var`` (an interface variable), the same for each
    of its aliases (FMI 2.0, 2.2.7; an Enumeration takes the Integers' references)."""
    return ("Integer" if var.type == "Enumeration" else var.type, var.value_reference)


def aliased_target(ref: str, scenario: Any) -> Any:
    """The connection of ``scenario`` that drives ``ref`` (``"<instance>.<variable>"``)
    under its name or an alias's, None if none does."""
    instance, _, variable = ref.partition(".")
    key = alias_key(scenario.instances[instance].interface.variables[variable])
    for c in scenario.connections:
        if c.target_instance == instance:
            target = scenario.instances[instance].interface.variables[c.target_variable]
            if alias_key(target) == key:
                return c
    return None


def with_article(word: str) -> str:
    """``word`` with its indefinite article ("an input", "a parameter")."""
    return ("an " if word[0] in "aeiou" else "a ") + word
