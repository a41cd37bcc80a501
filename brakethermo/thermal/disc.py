"""Disc datasheet: geometry and temperature-dependent material properties."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brakethermo.config import load_toml, resolve_named
from brakethermo.errors import ConfigError

BAR = 1.0e5  # Pa
KMH = 1.0 / 3.6  # m/s


@dataclass(frozen=True)
class DiscSpec:
    """A brake-disc datasheet (CHANNELS.md §5), SI units.

    Attributes
    ----------
    id : str
        Datasheet identifier (``cc-340-8``).
    r_int, r_est : float — m
        Inner and outer radius of the carbon ring.
    thickness : float — m
        Disc thickness ``s``.
    pad_r1, pad_r4 : float — m
        Radial limits of the pad contact band, split into three equal crowns.
    spot_radii : tuple of float — m
        IR spot radii, spot 1..4.
    density : float — kg/m^3
    emissivity : float — dimensionless
    c_temp_c, c_value : tuple of float — degC, J/(kg K)
        Specific heat table, linear between points, held constant outside.
    k_temp_c, k_value : tuple of float — degC, W/(m K)
        Radial conductivity table, linear between points, held constant outside.
    torque_per_pa : float — N m/Pa
        Brake torque on this disc per line pressure at nominal friction.
    heat_share : float — dimensionless
        Share of the friction heat that enters the disc.
    tyre_rolling_radius : float — m
    window_c : tuple of float — degC
        Operating window.
    v_ref : float — m/s
        Reference speed of the h(V) normalisation.
    k_z : float or None — W/(m K)
        Nominal through-thickness conductivity (normal to the faces; varies between disc
        batches); ``None`` when the datasheet does not give it.
    """

    id: str
    r_int: float
    r_est: float
    thickness: float
    pad_r1: float
    pad_r4: float
    spot_radii: tuple[float, ...]
    density: float
    emissivity: float
    c_temp_c: tuple[float, ...]
    c_value: tuple[float, ...]
    k_temp_c: tuple[float, ...]
    k_value: tuple[float, ...]
    torque_per_pa: float
    heat_share: float
    tyre_rolling_radius: float
    window_c: tuple[float, float]
    v_ref: float
    k_z: float | None = None
    description: str = field(default="", compare=False)

    @property
    def crown_edges(self) -> np.ndarray:
        """Radii r_1..r_4 of the three equal pad crowns (eq. 7), m."""
        return np.linspace(self.pad_r1, self.pad_r4, 4)

    def specific_heat(self, temp_c: np.ndarray | float) -> np.ndarray:
        """c(T) in J/(kg K) for temperature in degC."""
        return np.interp(temp_c, self.c_temp_c, self.c_value)

    def conductivity(self, temp_c: np.ndarray | float) -> np.ndarray:
        """Radial k(T) in W/(m K) for temperature in degC."""
        return np.interp(temp_c, self.k_temp_c, self.k_value)

    def braking_power(self, pressure_pa: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """Friction heat entering the disc, W: ``share · torque_per_Pa · p · ω``."""
        return self.heat_share * self.torque_per_pa * np.asarray(pressure_pa) * np.abs(omega)


def load_disc(name_or_path: str | Path = "cc-340-8") -> DiscSpec:
    """Load and validate a disc datasheet by shipped id or TOML path."""
    path = resolve_named("discs", name_or_path)
    raw = load_toml(path)
    try:
        geo, mat, brk, op = raw["geometry"], raw["material"], raw["brake"], raw["operation"]
        spec = DiscSpec(
            id=str(raw.get("id", path.stem)),
            description=str(raw.get("description", "")),
            r_int=float(geo["r_int"]),
            r_est=float(geo["r_est"]),
            thickness=float(geo["thickness"]),
            pad_r1=float(geo["pad_band"][0]),
            pad_r4=float(geo["pad_band"][1]),
            spot_radii=tuple(float(r) for r in geo["spot_radii"]),
            density=float(mat["density"]),
            emissivity=float(mat["emissivity"]),
            c_temp_c=tuple(float(v) for v in mat["c_temp_c"]),
            c_value=tuple(float(v) for v in mat["c_value"]),
            k_temp_c=tuple(float(v) for v in mat["k_temp_c"]),
            k_value=tuple(float(v) for v in mat["k_value"]),
            torque_per_pa=float(brk["torque_per_bar"]) / BAR,
            heat_share=float(brk["heat_share"]),
            tyre_rolling_radius=float(brk["tyre_rolling_radius"]),
            window_c=(float(op["window_c"][0]), float(op["window_c"][1])),
            v_ref=float(op["v_ref_kmh"]) * KMH,
            k_z=float(mat["k_z"]) if "k_z" in mat else None,
        )
    except KeyError as exc:
        raise ConfigError(f"missing key {exc}", path=path) from None
    except (TypeError, ValueError, IndexError) as exc:
        raise ConfigError(f"invalid value ({exc})", path=path) from None
    _validate(spec, path)
    return spec


def _validate(spec: DiscSpec, path: Path) -> None:
    problems = []
    if not 0 < spec.r_int < spec.r_est:
        problems.append("need 0 < r_int < r_est")
    if not spec.r_int <= spec.pad_r1 < spec.pad_r4 <= spec.r_est:
        problems.append("pad_band must lie inside [r_int, r_est]")
    if len(spec.spot_radii) != 4 or not all(
        spec.r_int <= r <= spec.r_est for r in spec.spot_radii
    ):
        problems.append("spot_radii must be four radii inside the ring")
    for name, xs, ys in (
        ("c", spec.c_temp_c, spec.c_value),
        ("k", spec.k_temp_c, spec.k_value),
    ):
        if len(xs) != len(ys) or len(xs) < 1 or any(np.diff(xs) <= 0) or min(ys) <= 0:
            problems.append(f"{name} table needs increasing temperatures and positive values")
    if spec.k_z is not None and not (np.isfinite(spec.k_z) and spec.k_z > 0):
        problems.append("k_z must be a finite conductivity > 0")
    if spec.thickness <= 0 or spec.density <= 0 or not 0 < spec.emissivity <= 1:
        problems.append("thickness, density must be > 0 and 0 < emissivity <= 1")
    if problems:
        raise ConfigError("; ".join(problems), path=path)
