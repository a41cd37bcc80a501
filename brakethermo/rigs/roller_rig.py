"""The roller rig's datasheet (``configs/rigs/roller-rig.toml``) as a frozen dataclass."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from brakethermo.config import load_toml, require_rig_datasheet, resolve_named
from brakethermo.errors import ConfigError
from brakethermo.rigs.hertz import HertzContact, curvature_sums, hertz_contact
from brakethermo.rigs.kalker import KalkerCoefficients, kalker_coefficients
from brakethermo.rigs.motor import InductionMotor


@dataclass(frozen=True)
class Bearings:
    """Loss torque T = c0 sign(omega) + c1 omega per shaft: N m and N m s/rad."""

    wheel_coulomb: float
    wheel_viscous: float
    roller_coulomb: float
    roller_viscous: float


@dataclass(frozen=True)
class Friction:
    """Polach's friction law (paper eq. 7) and reduction factors: -, -, s/m, -, -."""

    mu0: float
    A: float
    B: float
    k_a: float
    k_s: float


@dataclass(frozen=True)
class FilterDefaults:
    """The paper's joint-UKF settings (eq. 15a-15c), SI units, the RK4 substep (s) and
    the process noise of the measured-noise tuning."""

    alpha: float
    beta: float
    kappa: float
    p0: tuple[float, float, float]
    q: tuple[float, float, float]
    r: tuple[float, float]
    substep: float
    q_measured: tuple[float, float, float]


@dataclass(frozen=True)
class RollerRigSpec:
    """Everything the roller-rig model needs to know about the machine.

    Attributes
    ----------
    id, description : str
    wheel_inertia, roller_inertia : float — kg m^2 (paper eq. 10).
    nominal_radius : float — wheel rolling radius the rig was built for, m.
    roller_radius : float — m.
    wheel_lateral_curvature, roller_lateral_curvature : float — 1/m.
    contact_angle : float — rad.
    young, poisson, shear_modulus : float — Pa, -, Pa.
    nominal_load : float — N.
    friction : Friction
    motor : InductionMotor
    bearings : Bearings
    filter : FilterDefaults
    path : Path — the datasheet file.
    """

    id: str
    description: str
    wheel_inertia: float
    nominal_radius: float
    wheel_lateral_curvature: float
    roller_inertia: float
    roller_radius: float
    roller_lateral_curvature: float
    contact_angle: float
    young: float
    poisson: float
    shear_modulus: float
    nominal_load: float
    friction: Friction
    motor: InductionMotor
    bearings: Bearings
    filter: FilterDefaults
    path: Path

    def contact(self, wheel_radius: float | None = None) -> HertzContact:
        """Hertz ellipse at the nominal load for a wheel of ``wheel_radius`` (m)."""
        A, B = curvature_sums(
            wheel_radius or self.nominal_radius, self.roller_radius,
            self.wheel_lateral_curvature, self.roller_lateral_curvature,
        )  # fmt: skip
        return hertz_contact(self.nominal_load, A, B, self.young, self.poisson)

    def kalker(self, wheel_radius: float | None = None) -> KalkerCoefficients:
        """Kalker's coefficients of the nominal ellipse."""
        c = self.contact(wheel_radius)
        return kalker_coefficients(c.b / c.a, self.poisson)

    def spin(self, wheel_radius: float | None = None) -> float:
        """Spin creepage sin(delta)/r_eq, 1/m (paper eq. 5b-6)."""
        r_w = wheel_radius or self.nominal_radius
        return math.sin(self.contact_angle) * (1.0 / r_w + 1.0 / self.roller_radius)


def _section(raw: dict[str, Any], name: str, path: Path) -> dict[str, Any]:
    sec = raw.get(name)
    if not isinstance(sec, dict):
        raise ConfigError(f"missing table [{name}]", path=path)
    return sec


def _num(
    sec: dict[str, Any],
    table: str,
    key: str,
    path: Path,
    *,
    lo: float = 0.0,
    lo_open: bool = True,
    hi: float = math.inf,
) -> float:
    where = f"[{table}] {key}"
    if key not in sec:
        raise ConfigError(f"missing key {where}", path=path)
    v = sec[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ConfigError(f"{where} must be a finite number, found {v!r}", path=path)
    ok = (v > lo if lo_open else v >= lo) and v <= hi
    if not ok:
        bound = f"{'>' if lo_open else '>='} {lo:g}" + ("" if hi == math.inf else f" and <= {hi:g}")
        raise ConfigError(f"{where} must be {bound}, found {v!r}", path=path)
    return float(v)


def _vec(sec: dict[str, Any], table: str, key: str, n: int, path: Path) -> tuple[float, ...]:
    v = sec.get(key)
    if (
        not isinstance(v, list)
        or len(v) != n
        or not all(
            isinstance(x, int | float) and not isinstance(x, bool) and x > 0 and math.isfinite(x)
            for x in v
        )
    ):
        raise ConfigError(
            f"[{table}] {key} must be a list of {n} positive numbers, found {v!r}", path=path
        )
    return tuple(float(x) for x in v)


def load_roller_rig(name_or_path: str | Path = "roller-rig") -> RollerRigSpec:
    """Load and validate a roller-rig datasheet by shipped name or path.

    Raises
    ------
    ConfigError
        Missing table or key, or a value out of range; the message names the file,
        the key, what was expected and what was found.
    """
    path = resolve_named("rigs", name_or_path)
    raw = load_toml(path)
    require_rig_datasheet(raw, "roller-rig", path)
    w, r = _section(raw, "wheel", path), _section(raw, "roller", path)
    c, fr = _section(raw, "contact", path), _section(raw, "friction", path)
    m, b = _section(raw, "roller_motor", path), _section(raw, "bearings", path)
    fl = _section(raw, "filter", path)
    pole_pairs = _num(m, "roller_motor", "pole_pairs", path, lo=1, lo_open=False)
    if pole_pairs != int(pole_pairs):
        raise ConfigError(
            f"[roller_motor] pole_pairs must be an integer, found {pole_pairs!r}", path=path
        )
    kappa = fl.get("kappa", 0.0)
    if isinstance(kappa, bool) or not isinstance(kappa, int | float) or not 3 + kappa > 0:
        raise ConfigError(f"[filter] kappa must be a number > -3, found {kappa!r}", path=path)
    spec = RollerRigSpec(
        id=str(raw.get("id", path.stem)),
        description=str(raw.get("description", "")),
        wheel_inertia=_num(w, "wheel", "inertia", path),
        nominal_radius=_num(w, "wheel", "nominal_radius", path, hi=2.0),
        wheel_lateral_curvature=_num(w, "wheel", "lateral_curvature", path, lo=-1e3, lo_open=False),
        roller_inertia=_num(r, "roller", "inertia", path),
        roller_radius=_num(r, "roller", "radius", path, hi=5.0),
        roller_lateral_curvature=_num(
            r, "roller", "lateral_curvature", path, lo=-1e3, lo_open=False
        ),
        contact_angle=_num(c, "contact", "contact_angle", path, lo=0.0, lo_open=False, hi=1.0),
        young=_num(c, "contact", "young", path),
        poisson=_num(c, "contact", "poisson", path, lo=0.0, lo_open=False, hi=0.49),
        shear_modulus=_num(c, "contact", "shear_modulus", path),
        nominal_load=_num(c, "contact", "nominal_load", path),
        friction=Friction(
            mu0=_num(fr, "friction", "mu0", path, hi=2.0),
            A=_num(fr, "friction", "A", path, hi=1.0),
            B=_num(fr, "friction", "B", path, lo=0.0, lo_open=False),
            k_a=_num(fr, "friction", "k_a", path, hi=1.0),
            k_s=_num(fr, "friction", "k_s", path, hi=1.0),
        ),
        motor=InductionMotor(
            v_th=_num(m, "roller_motor", "v_th", path),
            r_th=_num(m, "roller_motor", "r_th", path, lo=0.0, lo_open=False),
            x_th=_num(m, "roller_motor", "x_th", path, lo=0.0, lo_open=False),
            r2=_num(m, "roller_motor", "r2", path),
            x2=_num(m, "roller_motor", "x2", path, lo=0.0, lo_open=False),
            f_rated=_num(m, "roller_motor", "f_rated", path),
            pole_pairs=int(pole_pairs),
        ),
        bearings=Bearings(
            wheel_coulomb=_num(b, "bearings", "wheel_coulomb", path, lo_open=False),
            wheel_viscous=_num(b, "bearings", "wheel_viscous", path, lo_open=False),
            roller_coulomb=_num(b, "bearings", "roller_coulomb", path, lo_open=False),
            roller_viscous=_num(b, "bearings", "roller_viscous", path, lo_open=False),
        ),
        filter=FilterDefaults(
            alpha=_num(fl, "filter", "alpha", path, hi=1.0),
            beta=_num(fl, "filter", "beta", path, lo=0.0, lo_open=False),
            kappa=float(kappa),
            p0=_vec(fl, "filter", "p0", 3, path),  # type: ignore[arg-type]
            q=_vec(fl, "filter", "q", 3, path),  # type: ignore[arg-type]
            r=_vec(fl, "filter", "r", 2, path),  # type: ignore[arg-type]
            substep=_num(fl, "filter", "substep", path, hi=0.01),
            q_measured=_vec(fl, "filter", "q_measured", 3, path),  # type: ignore[arg-type]
        ),
        path=path,
    )
    if spec.friction.k_s > spec.friction.k_a:
        raise ConfigError(
            f"[friction] needs k_s <= k_a (Polach), found k_s={spec.friction.k_s:g} >"
            f" k_a={spec.friction.k_a:g}", path=path,
        )  # fmt: skip
    return spec
