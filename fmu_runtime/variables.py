"""Typed helpers both FMUs use to bind FMI variables to their Python storage.

pythonfmu reads and writes a variable through a ``getter()`` and a ``setter(value)``. Our
FMUs keep most values in containers (a numpy state vector, a dict of parameters, a list of
outputs), so a variable is bound to one item of a container: :func:`item_getter` /
:func:`item_setter`. A variable kept as an attribute of the slave is bound through a weak
reference (:func:`attribute_getter` / :func:`attribute_setter`, the defaults
:meth:`fmu_runtime.safe_slave.SafeSlave.register` installs): pythonfmu's own defaults are
closures over the slave, a reference cycle (slave -> variables -> closure -> slave) that
leaves every freed instance, hundreds of objects, to the cyclic garbage collector instead
of freeing it in ``fmi2FreeInstance``. No helper here holds a strong reference to a slave.

:func:`field_bounds` reads the range a field of a parameter record declares (``gt``/``ge``/
``lt``/``le``, e.g. :class:`plant_fmu.model.validated.FieldInfo`), so an FMU parameter
generated from a record's field declares the same ``min``/``max`` in modelDescription.xml
(through :meth:`fmu_runtime.safe_slave.SafeSlave.register`) without re-typing it.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Hashable
from typing import Any, Protocol


class Items(Protocol):
    """A container indexed by a key (a list, a numpy array, a dict). The key type is not a
    type parameter: mypy cannot infer one from numpy's overloaded ``__getitem__``."""

    def __getitem__(self, key: Any, /) -> Any: ...

    def __setitem__(self, key: Any, value: Any, /) -> None: ...


def item_getter(values: Items, key: Hashable) -> Callable[[], Any]:
    """A pythonfmu getter returning ``values[key]`` at the time of the call."""

    def getter() -> Any:
        return values[key]

    return getter


def item_setter(values: Items, key: Hashable) -> Callable[[Any], None]:
    """A pythonfmu setter storing its value in ``values[key]``."""

    def setter(value: Any) -> None:
        values[key] = value

    return setter


def attribute_getter(owner: object, name: str) -> Callable[[], Any]:
    """A pythonfmu getter returning ``owner.<name>``, holding ``owner`` weakly."""
    ref = weakref.ref(owner)

    def getter() -> Any:
        return getattr(ref(), name)

    return getter


def attribute_setter(owner: object, name: str) -> Callable[[Any], None]:
    """A pythonfmu setter assigning ``owner.<name>``, holding ``owner`` weakly."""
    ref = weakref.ref(owner)

    def setter(value: Any) -> None:
        setattr(ref(), name, value)

    return setter


class Bounded(Protocol):
    """A field declaring an exclusive (``gt``/``lt``) or inclusive (``ge``/``le``) bound,
    None where it declares none."""

    @property
    def gt(self) -> float | None: ...

    @property
    def ge(self) -> float | None: ...

    @property
    def lt(self) -> float | None: ...

    @property
    def le(self) -> float | None: ...


def field_bounds(field: Bounded) -> tuple[float | None, float | None]:
    """``(minimum, maximum)`` a field declares (None where it declares none).

    FMI's ``min``/``max`` are inclusive, so a strict bound (``gt=0``) becomes the inclusive
    ``min = 0``: a looser range that importers can check, while the model's own validation
    still refuses the bound itself.
    """
    minimum = field.ge if field.gt is None else field.gt
    maximum = field.le if field.lt is None else field.lt
    return minimum, maximum
