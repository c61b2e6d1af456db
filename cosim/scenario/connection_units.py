"""Whether a connection would misread its value: the units its two Real variables declare.

The master passes numbers, not quantities, and converts nothing (as fmpy and FMI 2.0 masters
without SSP's unit conversions do). A connection whose ends declare units with different
definitions (FMI 2.0 ``UnitDefinitions``: the SI base-unit exponents, ``factor`` and
``offset``; a value v of the unit is ``factor * v + offset`` in SI) would hand the input
a number it reads in another unit: ``rad`` into ``deg``, ``m`` into ``N``. A unit without a
definition, or without a ``BaseUnit`` (only a name), is taken as it is.
"""

from __future__ import annotations

from typing import Any

BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")  # FMI 2.0's BaseUnit exponents


def declared_unit(model_description: Any, var: Any) -> tuple[str, Any] | None:
    """The unit of ``var`` (an fmpy ``ModelVariable`` of ``model_description``) as (name,
    fmpy ``BaseUnit`` or None), from the variable or its declared type; None when it
    declares none or is not a Real."""
    if var.type != "Real":
        return None
    name = var.unit or (var.declaredType.unit if var.declaredType is not None else None)
    if not name:
        return None
    units = {u.name: u.baseUnit for u in model_description.unitDefinitions}
    return name, units.get(name)


def unit_difference(source: tuple[str, Any, str], target: tuple[str, Any, str]) -> str | None:
    """Why the output ``source`` would drive the input ``target`` with a value in the wrong
    unit, or None. Each is (``"<instance>.<variable>"``, its FMU's fmpy model description,
    the fmpy ``ModelVariable``)."""
    (out_ref, out_md, out_var), (in_ref, in_md, in_var) = source, target
    source_unit, target_unit = declared_unit(out_md, out_var), declared_unit(in_md, in_var)
    if source_unit is None or target_unit is None:
        return None
    (out, a), (into, b) = source_unit, target_unit
    if a is None or b is None:
        return None
    # a relative quantity (a temperature difference) converts without the offsets
    relative = _relative(out_var) or _relative(in_var)
    offsets = 0.0 if relative else a.offset - b.offset
    if tuple(getattr(a, d) for d in BASE_UNITS) != tuple(getattr(b, d) for d in BASE_UNITS):
        why = "different quantities"
    elif a.factor != b.factor or offsets != 0.0:
        why = f"1 {out} is {(a.factor + offsets) / b.factor:.6g} {into}"
    else:
        return None
    return (
        f"{out_ref} is in {out} and {in_ref} in {into} ({why}): the master passes numbers, "
        f"not quantities, so {in_ref} would read a value in {out} as one in {into}; connect "
        "variables of one unit"
    )


def _relative(var: Any) -> bool:
    """FMI 2.0 ``relativeQuantity``, of the variable or its declared type."""
    declared = var.declaredType
    return bool(var.relativeQuantity or (declared is not None and declared.relativeQuantity))
