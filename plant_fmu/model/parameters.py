"""Vehicle parameter sets: load a TOML file into a validated, immutable object.

A parameter set is a TOML file whose tables (``[rigid_body]``, ``[added_mass]``, ...) only
group the keys for the reader: every key is a field of :class:`VehicleParameters`, named
after the symbol in ``docs/model.md#parameters`` (``X_uu`` is X_u|u|, ``K_pp`` is
K_p|p|, ...). A file may start from another set with ``base = "<name>"`` and override keys.

One gravity: a set states g, and its weight W = m g (the moving mass's weight m_v g and the
displaced fluid's mass B / g use the same g). A set whose W differs from m g (a neutrally
buoyant what-if, say) states why in a comment.

Every value is SI. Bad input raises :class:`VehicleParameterError` naming the field, the
value and what is allowed.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from plant_fmu.model import vehicle_toml
from plant_fmu.model.inertia import added_mass_matrix, rigid_body_mass_matrix
from plant_fmu.model.validated import ANGULAR_FREQUENCY, CheckedRecord, checked_field


class VehicleParameterError(ValueError):
    """A parameter set is missing, unknown, or holds a value outside its allowed range."""


@dataclass(frozen=True)
class VehicleParameters(CheckedRecord):
    """Physical parameters of one vehicle variant (SI units, body origin at the CB).

    Validated and immutable (:class:`plant_fmu.model.validated.CheckedRecord`: every field
    is checked against its range when a set is made, then the mass matrix), hashable.
    """

    error_type = VehicleParameterError

    name: str = checked_field("custom", description="name of the set")
    description: str = checked_field("", description="what the set is")

    # Rigid body (Tables 5.1 and 5.4; length and diameter Table 4.1)
    m: float = checked_field(gt=0.0, description="vehicle mass, kg")
    W: float = checked_field(gt=0.0, description="weight, N (m g; a set that differs says why)")
    B: float = checked_field(gt=0.0, description="buoyancy, N")
    g: float = checked_field(gt=0.0, description="gravitational acceleration, m/s^2 (one for all)")
    I_xx: float = checked_field(gt=0.0, description="roll inertia about the origin, kg m^2")
    I_yy: float = checked_field(gt=0.0, description="pitch inertia about the origin, kg m^2")
    I_zz: float = checked_field(gt=0.0, description="yaw inertia about the origin, kg m^2")
    x_g: float = checked_field(description="x of the centre of gravity, m")
    z_g: float = checked_field(description="z of the centre of gravity (down positive), m")
    length: float = checked_field(gt=0.0, description="hull length, m")
    diameter: float = checked_field(gt=0.0, description="hull diameter, m")

    # Added mass (Tables 5.1, 5.4 and 6.1)
    a11: float = checked_field(ge=0.0, description="surge added mass, kg")
    a22: float = checked_field(ge=0.0, description="sway added mass, kg")
    a33: float = checked_field(ge=0.0, description="heave added mass, kg")
    a44: float = checked_field(ge=0.0, description="roll added inertia, kg m^2")
    a55: float = checked_field(ge=0.0, description="pitch added inertia, kg m^2")
    a66: float = checked_field(ge=0.0, description="yaw added inertia, kg m^2")
    a26: float = checked_field(description="sway-yaw added mass coupling, kg m")
    a35: float = checked_field(description="heave-pitch added mass coupling, kg m")

    # Viscous terms (4.2.6)-(4.2.9), Tables 5.1, 5.4, 6.3
    X_uu: float = checked_field(description="surge drag X_u|u| (times u_r|u_r|), kg/m")
    Y_vv: float = checked_field(description="sway cross-flow drag Y_v|v| (times v_r|v_r|), kg/m")
    Y_rr: float = checked_field(description="sway force from yaw rate Y_r|r| (times r|r|), kg m")
    Y_uv: float = checked_field(description="body and fin lift in sway Y_uv (times u_r v_r), kg/m")
    Y_ur: float = checked_field(description="fin lift in sway from yaw rate Y_ur (times u_r r), kg")
    N_vv: float = checked_field(description="yaw moment from sway N_v|v| (times v_r|v_r|), kg")
    N_rr: float = checked_field(description="yaw cross-flow damping N_r|r| (times r|r|), kg m^2")
    N_uv: float = checked_field(
        description="yaw moment N_uv of body and fin lift without the Munk moment, which the "
        "added mass gives (times u_r v_r), kg"
    )
    N_ur: float = checked_field(
        description="fin lift moment in yaw from yaw rate N_ur (times u_r r), kg m"
    )
    K_p: float = checked_field(description="linear roll damping K_p, N m s")
    K_pp: float = checked_field(description="quadratic roll damping K_p|p| (times p|p|), kg m^2")
    Z_ww: float = checked_field(description="heave cross-flow drag Z_w|w| (times w_r|w_r|), kg/m")
    Z_qq: float = checked_field(description="heave force from pitch rate Z_q|q| (times q|q|), kg m")
    Z_uw: float = checked_field(description="body and fin lift in heave Z_uw (times u_r w_r), kg/m")
    Z_uq: float = checked_field(
        description="fin lift in heave from pitch rate Z_uq (times u_r q), kg"
    )
    M_ww: float = checked_field(description="pitch moment from heave M_w|w| (times w_r|w_r|), kg")
    M_qq: float = checked_field(description="pitch cross-flow damping M_q|q| (times q|q|), kg m^2")
    M_uw: float = checked_field(
        description="body and fin lift moment in pitch M_uw (times u_r w_r), kg"
    )
    M_uq: float = checked_field(
        description="fin lift moment in pitch from pitch rate M_uq (times u_r q), kg m"
    )

    # Stern planes (Table 6.1), scaled with u_r |u_r| / fin_reference_speed^2
    Z_ds: float = checked_field(
        description="fin heave force per fin angle at the reference speed, N/rad"
    )
    M_ds: float = checked_field(
        description="fin pitch moment per fin angle at the reference speed, N m/rad"
    )
    fin_reference_speed: float = checked_field(gt=0.0, description="speed Z_ds, M_ds hold at, m/s")

    # Internal moving mass (6.3.12)-(6.3.16)
    m_v: float = checked_field(gt=0.0, description="moving mass, kg")
    x_v: float = checked_field(description="x of the moving-mass rail, m")
    mass_natural_frequency: float = checked_field(
        gt=0.0, description="servo omega_n, rad/s", quantity=ANGULAR_FREQUENCY
    )
    mass_damping_ratio: float = checked_field(gt=0.0, description="servo damping ratio zeta, 1")
    mass_stroke: float = checked_field(gt=0.0, description="rail stop |y_v| <= stroke, m")
    mass_speed_limit: float = checked_field(ge=0.0, description="rail speed limit, m/s (0 = off)")

    # Thrusters
    z_t: float = checked_field(default=0.0, description="tunnel-thruster z in body axes, m")

    def _check_record(self) -> None:
        self._check_inside_hull()
        self._check_servo()
        if not self.m_v < self.m:
            raise ValueError(
                f"m_v = {self.m_v!r} kg: expected less than m = {self.m!r} kg (the moving "
                "mass is part of the vehicle's mass m, which counts it at the rail's middle)"
            )
        with np.errstate(all="ignore"):  # numpy's warnings would reach an FMU host's stderr
            total = rigid_body_mass_matrix(self) + added_mass_matrix(self)
            symmetric = 0.5 * (total + total.T)
        if not np.all(np.isfinite(symmetric)):
            raise ValueError(
                "M_RB + M_A overflows: its entries are beyond any double (check m, the "
                "inertias and the added masses for values like 1e308)"
            )
        self._check_parallel_axis()
        try:  # LAPACK's Cholesky: exact enough whatever the entries' spread, where the
            np.linalg.cholesky(symmetric)  # eigenvalues round by 1e-16 of the largest
        except np.linalg.LinAlgError:
            eigenvalues = np.linalg.eigvalsh(symmetric)
            raise ValueError(
                f"M_RB + M_A must be positive definite, but its smallest eigenvalue is "
                f"{eigenvalues.min():.6g} (check a26, a35, x_g, z_g against the inertias)"
            ) from None

    def _check_parallel_axis(self) -> None:
        """Refuse a rigid body no material makes: its inertia about the body origin (the
        CB) is its inertia about the CG, positive definite, plus the parallel-axis share of
        the CG's offset r_g = (x_g, 0, z_g), m (|r_g|^2 - r_g r_g^T) in kg m^2; so M_RB is
        positive definite (the added mass must not be what makes M_RB + M_A so)."""
        x_g, z_g = self.x_g, self.z_g  # products, not powers: no OverflowError past 1e154
        shares = (("I_xx", "m z_g^2", self.m * z_g * z_g),
                  ("I_yy", "m (x_g^2 + z_g^2)", self.m * (x_g * x_g + z_g * z_g)),
                  ("I_zz", "m x_g^2", self.m * x_g * x_g))  # fmt: skip
        for name, what, share in shares:
            value = getattr(self, name)
            if not value > share:
                raise ValueError(
                    f"{name} = {value!r} kg m^2: expected more than {what} = {share:.4g} "
                    "kg m^2 (the inertia about the CB is the inertia about the CG plus "
                    "this, by the parallel-axis theorem)"
                )
        roll, yaw = self.I_xx - shares[0][2], self.I_zz - shares[2][2]
        if not roll * yaw > (self.m * x_g * z_g) * (self.m * x_g * z_g):
            raise ValueError(
                f"I_xx = {self.I_xx!r}, I_zz = {self.I_zz!r} kg m^2 with x_g = {self.x_g!r}, "
                f"z_g = {self.z_g!r} m: expected an inertia about the CG that is positive "
                "definite ((I_xx - m z_g^2)(I_zz - m x_g^2) > (m x_g z_g)^2)"
            )

    def _check_inside_hull(self) -> None:
        """Refuse a part placed outside the hull: the moving-mass rail (x_v), the tunnel
        thruster (z_t) and the centre of gravity (x_g, z_g; an average of the vehicle's own
        material) are inside it, and so is the body origin, the centre of buoyancy. The hull
        is a cylinder of this diameter and length, so a point inside it is within
        diameter / 2 of the axis and, wherever along the hull the origin lies, within one
        length of the origin along x."""
        bounds = (("x_v", "length", self.length), ("x_g", "length", self.length),
                  ("z_t", "diameter / 2", self.diameter / 2),
                  ("z_g", "diameter / 2", self.diameter / 2))  # fmt: skip
        for name, what, bound in bounds:
            value = getattr(self, name)
            if not abs(value) <= bound:
                raise ValueError(
                    f"{name} = {value!r} m: expected |{name}| <= {what} = {bound:.4g} m (it "
                    "is inside the hull, as the body origin, the centre of buoyancy, is)"
                )

    def _check_servo(self) -> None:
        """Refuse a moving-mass servo whose stiffness k_v or damping d_v (6.3.16) is beyond
        any double (it would step NaN, or raise an OverflowError), naming the largest
        omega_n (or zeta) that the other servo values, as given, take."""
        omega, zeta = self.mass_natural_frequency, self.mass_damping_ratio
        if _servo_is_finite(self.m_v, omega, zeta):
            return
        most = sys.float_info.max
        if not _servo_is_finite(self.m_v, omega, 0.0):  # k_v or m_v k_v overflows
            bound = _below(min(math.sqrt(most / self.m_v), math.sqrt(most) / self.m_v),
                           lambda w: _servo_is_finite(self.m_v, w, 0.0))  # fmt: skip
            raise ValueError(
                f"mass_natural_frequency = {omega!r} rad/s: expected at most {bound!r} rad/s "
                "(the servo stiffness k_v = m_v omega_n^2 (6.3.16) is beyond any double "
                "above that)"
            )
        bound = _below(most / (2.0 * self.m_v * omega),
                       lambda z: _servo_is_finite(self.m_v, omega, z))  # fmt: skip
        raise ValueError(
            f"mass_damping_ratio = {zeta!r}: expected at most {bound!r} (the servo damping "
            "d_v = 2 zeta m_v omega_n (6.3.16) is beyond any double above that)"
        )

    # Derived quantities (one place, so nothing re-types them)
    @property
    def k_v(self) -> float:
        """Servo stiffness k_v = m_v omega_n^2, N/m (6.3.16)."""
        return self.m_v * self.mass_natural_frequency**2

    @property
    def d_v(self) -> float:
        """Servo damping d_v = 2 zeta sqrt(m_v k_v), N s/m (6.3.16)."""
        return 2.0 * self.mass_damping_ratio * math.sqrt(self.m_v * self.k_v)

    @property
    def m_bar(self) -> float:
        """Mass of the displaced fluid B/g, kg."""
        return self.B / self.g

    def replace(self, **changes: Any) -> VehicleParameters:
        """A validated copy with some fields changed (``p.replace(W=306.0, z_g=0.0)``)."""
        return _validate({**self.as_dict(), **changes}, source=f"{self.name} (modified)")

    def with_stroke(self, stroke: float) -> VehicleParameters:
        """A copy whose rail stops are at ``stroke`` (m), checked as any field but allowed
        beyond the hull: the model's own what-if of a stop out of the mass's reach (the
        two-body stepping before a stop, a continuation past the stroke), which no
        vehicle file or written-over value may give (:func:`check_rail_in_hull`)."""
        values = {**self.as_dict(), "mass_stroke": stroke}
        try:
            return VehicleParameters.from_mapping(values)
        except VehicleParameterError as exc:
            raise VehicleParameterError(f"vehicle {self.name + ' (modified)'!r}: {exc}") from None


def _servo_is_finite(m_v: float, omega: float, zeta: float) -> bool:
    """Whether k_v and d_v, computed as :attr:`VehicleParameters.k_v` and
    :attr:`~VehicleParameters.d_v` compute them, are finite for this servo."""
    try:
        k_v = m_v * omega**2
    except OverflowError:  # a float's ** raises where its * gives inf
        return False
    return math.isfinite(k_v) and math.isfinite(2.0 * zeta * math.sqrt(m_v * k_v))


def _below(bound: float, taken: Callable[[float], bool]) -> float:
    """``bound`` or the double below it that ``taken`` accepts (a bound computed by
    division and square root may round a few ulps above the largest value taken)."""
    while not taken(bound):
        bound = math.nextafter(bound, 0.0)
    return bound


def check_rail_in_hull(params: VehicleParameters) -> None:
    """Refuse a set whose moving mass's stops are outside the hull: the rail runs along
    body y across a hull of ``diameter``, so ``mass_stroke`` (m) is at most its radius.

    Raises:
        VehicleParameterError: naming ``mass_stroke``, its value and the bound.
    """
    radius = params.diameter / 2
    if not params.mass_stroke <= radius:
        raise VehicleParameterError(
            f"mass_stroke = {params.mass_stroke!r} m: expected mass_stroke <= diameter / 2 "
            f"= {radius:.4g} m (the moving mass slides across the hull on a rail along body "
            "y, and its stops are inside the hull)"
        )


def vehicle_folder(package_root: str | Path | None = None) -> Path:
    """The folder of the built-in parameter sets (``plant_fmu/model/vehicles``).

    ``package_root`` is a folder holding the ``plant_fmu`` package, such as an FMU's
    ``resources/``; without it, the folder beside this module. Resolved at each call,
    never at import: an FMU's modules stay imported across extractions, so an FMU instance
    passes the resources folder it was instantiated with.
    """
    if package_root is None:
        return Path(__file__).resolve().parent / "vehicles"
    return Path(package_root, *__name__.split(".")[:-1], "vehicles")


def builtin_vehicles(folder: Path | None = None) -> list[str]:
    """Names of the parameter sets in ``folder`` (default :func:`vehicle_folder`)."""
    folder = vehicle_folder() if folder is None else folder
    return sorted(p.name.removesuffix(".toml") for p in folder.glob("*.toml"))


def load_vehicle(
    name_or_path: str | Path = "remus100", folder: Path | None = None
) -> VehicleParameters:
    """Load a built-in set by name (``remus100``, from ``folder``, default
    :func:`vehicle_folder`), a TOML file by path, or a set given inline: a value holding a
    line break is the TOML text itself (what an SSP or OSP export writes, so that the
    set travels with the system structure instead of a path no host resolves).

    A set is immutable, so a process parses and validates it once and hands out the same
    object for as long as the files it was read from hold the same text: an FMU instance
    loads its set when it is created, when it is initialised and in the controller's
    design, in every run of a study (~1 ms each, most of it TOML parsing and validation;
    reading the files again to compare takes microseconds).
    """
    folder = vehicle_folder() if folder is None else folder
    path = Path(name_or_path if not is_inline(str(name_or_path)) else "")
    relative = path.suffix == ".toml" and not path.is_absolute()  # a built-in name is not
    key = (str(name_or_path), str(folder), os.getcwd() if relative else "")
    cached = _loaded.get(key)
    if cached is not None and all(_text(path) == text for path, text in cached[0]):
        return cached[1]
    read: list[tuple[Path, str]] = []
    table = _read_table(str(name_or_path), seen=(), folder=folder, read=read)
    params = _validate(table, source=_source(str(name_or_path)))
    if len(_loaded) >= _LOADED_KEPT:
        del _loaded[next(iter(_loaded))]  # the oldest
    _loaded[key] = (tuple(read), params)
    return params


# UTF-8 whatever the host's locale (an FMU's host may run under LANG=C), a byte-order
# mark (some Windows editors write one) dropped
VEHICLE_ENCODING = "utf-8-sig"
_LOADED_KEPT = 64  # sets kept by load_vehicle (per name, folder and, for a relative
# path, working directory)
_loaded: dict[tuple[str, str, str], tuple[tuple[tuple[Path, str], ...], VehicleParameters]] = {}


def _text(path: Path) -> str | None:
    """A file's text, None if it cannot be read."""
    try:
        return path.read_text(encoding=VEHICLE_ENCODING)
    except (OSError, UnicodeDecodeError):
        return None


def is_inline(name_or_path: str) -> bool:
    """A vehicle value that is the set's TOML text, not a name or a path: it has a line
    break (a TOML table of more than one key does; a file or set name never does)."""
    return "\n" in name_or_path


def _source(name_or_path: str) -> str:
    """How a refusal names the set: its name or path, or "(given inline)"."""
    return "(given inline)" if is_inline(name_or_path) else name_or_path


def _read_table(
    name_or_path: str,
    seen: tuple[str, ...],
    folder: Path,
    read: list[tuple[Path, str]],
) -> dict[str, Any]:
    """The flat table of a set and of the sets it is based on; each file read is
    appended to ``read`` with its text."""
    if name_or_path in seen:
        raise VehicleParameterError(f"vehicle 'base' chain loops: {' -> '.join(seen)}")
    if is_inline(name_or_path):
        return _table_of(name_or_path, _source(name_or_path), seen, folder, read)
    path = Path(name_or_path)
    builtin = builtin_vehicles(folder)
    if name_or_path in builtin:
        path = folder.joinpath(f"{name_or_path}.toml")
    elif not (path.suffix == ".toml" and path.is_file()):
        where = (
            ""
            if path.is_absolute() or path.suffix != ".toml"
            else f" (a relative path is taken from the working directory, {os.getcwd()}: "
            "give an absolute path)"
        )
        raise VehicleParameterError(
            f"unknown vehicle {name_or_path!r}: expected one of {builtin} "
            f"or the path of an existing .toml file{where}"
        )
    try:
        text = path.read_text(encoding=VEHICLE_ENCODING)
    except UnicodeDecodeError as exc:
        raise VehicleParameterError(f"vehicle file {name_or_path!r}: not UTF-8 ({exc})") from None
    read.append((path.resolve(), text))
    return _table_of(text, name_or_path, seen, folder, read, beside=path.parent)


def _table_of(
    text: str,
    source: str,
    seen: tuple[str, ...],
    folder: Path,
    read: list[tuple[Path, str]],
    beside: Path | None = None,
) -> dict[str, Any]:
    """The flat table of the set whose TOML ``text`` came from ``source`` (a file, or
    "(given inline)"), its ``base`` chain read too: a relative path there names a file
    ``beside`` the one read (its folder; the working directory for a set given inline)."""
    try:
        table = vehicle_toml.loads(text)
    except vehicle_toml.VehicleTomlError as exc:
        raise VehicleParameterError(f"vehicle file {source!r}: {exc}") from None
    flat = _flatten(table, source=source)
    base = flat.pop("base", None)
    if base is None:
        return flat
    base = str(base)
    if beside is not None and base.endswith(".toml") and not Path(base).is_absolute():
        base = os.path.normpath(beside / base)  # normalised: a loop names each file once
    return {**_read_table(base, seen=(*seen, source), folder=folder, read=read), **flat}


def _flatten(table: dict[str, Any], source: str) -> dict[str, Any]:
    """Tables only group keys: lift every key to the top level, refusing duplicates."""
    flat: dict[str, Any] = {}
    for key, value in table.items():
        items = value.items() if isinstance(value, dict) else [(key, value)]
        for sub_key, sub_value in items:
            if sub_key in flat:
                raise VehicleParameterError(f"{source}: key {sub_key!r} is given twice")
            flat[sub_key] = sub_value
    return flat


def _validate(values: dict[str, Any], source: str) -> VehicleParameters:
    """The set of ``values`` as given (a file, a name, text or written-over values),
    checked as a whole, its rail inside its hull; errors name ``source``."""
    try:
        _check_some_parameter(values)
        params = VehicleParameters.from_mapping(values)
        check_rail_in_hull(params)
        return params
    except VehicleParameterError as exc:
        raise VehicleParameterError(f"vehicle {source!r}: {exc}") from None


_KEYS_SHOWN = 5  # keys a refusal of a file that is no vehicle set names


def _check_some_parameter(values: dict[str, Any]) -> None:
    """Refuse a table none of whose keys is a vehicle parameter (a scenario or study file
    given as a vehicle) in a short line, not as each of its keys unknown and each
    parameter missing."""
    physical = set(VehicleParameters.field_info()) - {"name", "description"}
    if physical & set(values):
        return
    keys = list(values)
    shown = ", ".join(keys[:_KEYS_SHOWN]) + (", ..." if len(keys) > _KEYS_SHOWN else "")
    raise VehicleParameterError(
        f"no vehicle parameter set: none of its keys ({shown or 'none'}) is a vehicle "
        "parameter: expected keys m, W, B, ... as in plant_fmu/model/vehicles/remus100.toml "
        "(docs/model.md#parameters)"
    )
