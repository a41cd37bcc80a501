"""Disc datasheet: geometry and temperature-dependent material properties."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brakethermo.config import config_file, resolve_named
from brakethermo.errors import ConfigError

BAR = 1.0e5  # Pa
KMH = 1.0 / 3.6  # m/s
# degC: where a through-thickness conductivity relative to k(T) is stated in W/(m K) (the
# estimation model's k_z follows k(T), the diagnosis's is a constant); mid-window of a
# carbon disc, and the temperature the simulator states its truth k_z at
KZ_REF_C = 400.0


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


def kz_scales(disc: DiscSpec, kz_ratio: float) -> dict[str, float]:
    """A through-thickness conductivity given relative to the in-plane ``k(T)`` (the
    estimation model's ``kz_ratio``: ``k_z = kz_ratio · k(T)``), on the other two scales:
    W/(m K) at :data:`KZ_REF_C`, and over the datasheet's nominal ``k_z`` (the scale of
    diagnose's ``kz_over_nominal``; left out when the datasheet gives no ``k_z``).

    Parameters
    ----------
    disc : DiscSpec
    kz_ratio : float — dimensionless, k_z / k(T)

    Returns
    -------
    dict — ``k_z_ref_c`` (degC), ``k_z_w_mk`` (W/(m K)) and ``kz_over_nominal``
    """
    k_z = float(kz_ratio * disc.conductivity(KZ_REF_C))
    out = {"k_z_ref_c": KZ_REF_C, "k_z_w_mk": k_z}
    if disc.k_z:
        out["kz_over_nominal"] = k_z / disc.k_z
    return out


def load_disc(name_or_path: str | Path = "cc-340-8") -> DiscSpec:
    """Load and validate a disc datasheet by shipped id or TOML path."""
    path = resolve_named("discs", name_or_path)
    raw = config_file(path)
    geo, mat, brk, op = (raw.table(k) for k in ("geometry", "material", "brake", "operation"))
    band = geo.numbers("pad_band", length=2, positive=True)
    window = op.numbers("window_c", length=2, lo=-50.0, hi=3000.0)
    op.check(window[0] < window[1], "window_c", "[low, high] with low < high", list(window))
    spec = DiscSpec(
        id=raw.string("id", path.stem),
        description=raw.string("description", ""),
        r_int=geo.number("r_int", positive=True),
        r_est=geo.number("r_est", positive=True),
        thickness=geo.number("thickness", positive=True),
        pad_r1=band[0],
        pad_r4=band[1],
        spot_radii=geo.numbers("spot_radii", length=4, positive=True),
        density=mat.number("density", positive=True),
        emissivity=mat.number("emissivity", positive=True, hi=1.0),
        c_temp_c=mat.numbers("c_temp_c"),
        c_value=mat.numbers("c_value", positive=True),
        k_temp_c=mat.numbers("k_temp_c"),
        k_value=mat.numbers("k_value", positive=True),
        torque_per_pa=brk.number("torque_per_bar", positive=True) / BAR,
        heat_share=brk.number("heat_share", positive=True, hi=1.0),
        tyre_rolling_radius=brk.number("tyre_rolling_radius", positive=True),
        window_c=(window[0], window[1]),
        v_ref=op.number("v_ref_kmh", positive=True) * KMH,
        k_z=mat.number("k_z", positive=True) if mat.has("k_z") else None,
    )
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
    if spec.thickness <= 0 or spec.density <= 0 or not 0 < spec.emissivity <= 1:
        problems.append("thickness, density must be > 0 and 0 < emissivity <= 1")
    if problems:
        raise ConfigError("; ".join(problems), path=path)
