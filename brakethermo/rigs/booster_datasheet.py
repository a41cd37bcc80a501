"""E-Booster bench datasheet (``configs/rigs/*.toml``) as a validated frozen dataclass."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from brakethermo.config import load_toml, require_rig_datasheet, resolve_named
from brakethermo.errors import ConfigError

DEFAULT_BENCH = "ebooster"


@dataclass(frozen=True)
class BoosterSpec:
    """Nominal bench data and observer settings; units in the attribute names.

    Attributes
    ----------
    id : str
    area_mm2 : float — mm^2, master-cylinder piston area A_mc.
    return_spring_n_per_mm : float — N/mm, return spring k_r (eq. 10).
    stroke_mm : float — mm, usable screw stroke (scales the p-V regressor).
    discharge_coeff : float — orifice discharge coefficient C_q.
    fluid_density : float — kg/m^3.
    orifice_area_mm2 : tuple of float — mm^2, front and rear ports.
    stiffness_mpa_per_cm3 : tuple of float — MPa/cm^3, E_w / V of front and rear circuits.
    input_area_mm2, servo_area_mm2 : float — mm^2, reaction-disk areas A_1, A_2.
    delta_noise_mm : float — mm, 1 sigma of the delta sensor.
    pedal_dof : int — N, degrees of freedom of the chi-square pedal force.
    pedal_tau_s : float — s, correlation time of the Gaussian processes behind it.
    pedal_state : str — how the observer carries the pedal force: ``"force"`` (one
        Gaussian state with the chi-square's mean, variance and correlation time) or
        ``"chi_square"`` (N unit Gaussian states w_i, F = F_scale sum w_i^2).
    q_pressure_mpa : tuple of float — MPa^2 per ms, process noise of p_m, p_f, p_r.
    q_zeta : tuple of float — mm^2 and (mm/s)^2 per ms, process noise of zeta1, zeta2.
    q_pm_speed : float — MPa^2 per ms, extra p_m noise at a screw speed of 50 mm/s
        (proportional to the speed).
    pv_relax_s : float — s, relaxation of p_m towards the p-V curve.
    pv_shift_sd_mm : float — mm, 1 sigma of where a session's p-V curve sits along the
        stroke against the training session's (seal, rubber and fluid state move it
        between sessions); widens the pressure bands by the curve's slope times it.
    alpha, beta, kappa : float — sigma-point scaling.
    p0_pressure_mpa : float — MPa, prior 1 sigma of the pressures.
    p0_zeta : tuple of float — mm and mm/s, prior 1 sigma of zeta1, zeta2.
    forgetting : float — RLS forgetting factor lambda.
    rls_delta : float — RLS P_0 = I / delta.
    min_travel_mm : float — mm, least screw travel of a usable training session.
    """

    id: str
    area_mm2: float
    return_spring_n_per_mm: float
    stroke_mm: float
    discharge_coeff: float
    fluid_density: float
    orifice_area_mm2: tuple[float, float]
    stiffness_mpa_per_cm3: tuple[float, float]
    input_area_mm2: float
    servo_area_mm2: float
    delta_noise_mm: float
    pedal_dof: int
    pedal_tau_s: float
    pedal_state: str
    q_pressure_mpa: tuple[float, float, float]
    q_zeta: tuple[float, float]
    q_pm_speed: float
    pv_relax_s: float
    pv_shift_sd_mm: float
    alpha: float
    beta: float
    kappa: float
    p0_pressure_mpa: float
    p0_zeta: tuple[float, float]
    forgetting: float
    rls_delta: float
    min_travel_mm: float
    description: str = field(default="", compare=False)

    @property
    def area_ratio(self) -> float:
        """A_1 / (A_1 + A_2): share of the output force the input rod carries at delta = 0."""
        return self.input_area_mm2 / (self.input_area_mm2 + self.servo_area_mm2)


_POSITIVE = (
    "area_mm2", "stroke_mm", "discharge_coeff", "fluid_density", "input_area_mm2",
    "servo_area_mm2", "delta_noise_mm", "pedal_tau_s", "pv_relax_s", "alpha", "p0_pressure_mpa",
    "rls_delta", "min_travel_mm", "q_pm_speed", "pv_shift_sd_mm",
)


def _get(raw: dict[str, Any], table: str, key: str, path: Path, n: int = 0) -> Any:
    """raw[table][key] as float (n = 0) or a tuple of n floats, else a ConfigError."""
    if table not in raw or key not in raw[table]:
        raise ConfigError(f"missing key '{table}.{key}'", path=path)
    value = raw[table][key]
    try:
        if n == 0:
            if isinstance(value, bool):
                raise TypeError
            return float(value)
        if not isinstance(value, list) or len(value) != n:
            raise TypeError
        return tuple(float(v) for v in value)
    except (TypeError, ValueError):
        expected = "a number" if n == 0 else f"a list of {n} numbers"
        raise ConfigError(
            f"key '{table}.{key}' must be {expected}, found {value!r}", path=path
        ) from None


PEDAL_STATES = ("force", "chi_square")


def _pedal_state(raw: dict[str, Any], table: str, path: Path) -> str:
    value = raw.get(table, {}).get("pedal_state")
    if value not in PEDAL_STATES:
        raise ConfigError(
            f"key '{table}.pedal_state' must be one of {', '.join(PEDAL_STATES)}, "
            f"found {value!r}", path=path,
        )
    return str(value)


def load_booster(name_or_path: str | Path = DEFAULT_BENCH) -> BoosterSpec:
    """Load and validate a bench datasheet by shipped name (``ebooster``) or TOML path.

    Raises
    ------
    ConfigError
        A missing key, a wrong type or a value out of range, naming file, key,
        expected and found.
    """
    path = resolve_named("rigs", name_or_path)
    raw = load_toml(path)
    require_rig_datasheet(raw, "ebooster", path)
    mc, ci, rd, se, ob, tr = (
        "master_cylinder", "circuits", "reaction_disk", "sensors", "observer", "training",
    )
    dof = _get(raw, ob, "pedal_dof", path)
    if dof != int(dof) or not 1 <= dof <= 8:
        raise ConfigError(f"key 'observer.pedal_dof' must be an integer 1..8, found {dof}",
                          path=path)
    spec = BoosterSpec(
        id=str(raw.get("id", path.stem)),
        description=str(raw.get("description", "")),
        area_mm2=_get(raw, mc, "area_mm2", path),
        return_spring_n_per_mm=_get(raw, mc, "return_spring_n_per_mm", path),
        stroke_mm=_get(raw, mc, "stroke_mm", path),
        discharge_coeff=_get(raw, ci, "discharge_coeff", path),
        fluid_density=_get(raw, ci, "fluid_density", path),
        orifice_area_mm2=(_get(raw, ci, "orifice_area_front_mm2", path),
                          _get(raw, ci, "orifice_area_rear_mm2", path)),
        stiffness_mpa_per_cm3=(_get(raw, ci, "stiffness_front_mpa_per_cm3", path),
                               _get(raw, ci, "stiffness_rear_mpa_per_cm3", path)),
        input_area_mm2=_get(raw, rd, "input_area_mm2", path),
        servo_area_mm2=_get(raw, rd, "servo_area_mm2", path),
        delta_noise_mm=_get(raw, se, "delta_noise_mm", path),
        pedal_dof=int(dof),
        pedal_tau_s=_get(raw, ob, "pedal_tau_s", path),
        pedal_state=_pedal_state(raw, ob, path),
        q_pressure_mpa=_get(raw, ob, "q_pressure_mpa", path, 3),
        q_zeta=_get(raw, ob, "q_zeta", path, 2),
        q_pm_speed=_get(raw, ob, "q_pm_speed", path),
        pv_relax_s=_get(raw, ob, "pv_relax_s", path),
        pv_shift_sd_mm=_get(raw, ob, "pv_shift_sd_mm", path),
        alpha=_get(raw, ob, "alpha", path),
        beta=_get(raw, ob, "beta", path),
        kappa=_get(raw, ob, "kappa", path),
        p0_pressure_mpa=_get(raw, ob, "p0_pressure_mpa", path),
        p0_zeta=_get(raw, ob, "p0_zeta", path, 2),
        forgetting=_get(raw, tr, "forgetting", path),
        rls_delta=_get(raw, tr, "rls_delta", path),
        min_travel_mm=_get(raw, tr, "min_travel_mm", path),
    )
    _validate(spec, path)
    return spec


def _validate(spec: BoosterSpec, path: Path) -> None:
    for name in _POSITIVE:
        value = getattr(spec, name)
        if not value > 0:
            raise ConfigError(f"key '{name}' must be > 0, found {value}", path=path)
    for name in ("orifice_area_mm2", "stiffness_mpa_per_cm3", "q_pressure_mpa", "q_zeta",
                 "p0_zeta"):
        values = getattr(spec, name)
        if not all(v > 0 for v in values):
            raise ConfigError(f"key '{name}' must hold values > 0, found {values}", path=path)
    if spec.return_spring_n_per_mm < 0:
        raise ConfigError(
            f"key 'return_spring_n_per_mm' must be >= 0, found {spec.return_spring_n_per_mm}",
            path=path,
        )
    if not 0.9 <= spec.forgetting <= 1.0:
        raise ConfigError(
            f"key 'training.forgetting' must be in [0.9, 1], found {spec.forgetting}", path=path
        )
