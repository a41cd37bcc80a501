"""The named unmodelled effects of the simulator and their mild / strong levels.

Every effect is always present at a mild level; ``--effects a,b`` switches the named
ones to their strong level. Names are fixed by OUTPUTS.md.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass

from brakethermo.errors import ConfigError

EFFECT_NAMES = (
    "power_distribution",
    "h_speed_knee",
    "slipstream",
    "friction_temperature",
    "thickness_gradient",
    "sensor_lag",
    "emissivity_error",
)


@dataclass(frozen=True)
class Effects:
    """Effect parameters of one run.

    Attributes
    ----------
    crown_base_concentration : float
        Dirichlet concentration of each corner's base pad-crown weights w_1..w_3
        (small = strongly non-uniform; large = near 1/3 each).
    crown_event_concentration : float
        Dirichlet concentration of the per-braking scatter around the corner's base.
    knee_gain : float
        Relative rise of h at V_ref over the low-speed law, growing as
        ``((V - V_k) / (V_ref - V_k))^2`` above the knee ``V_k = 0.8 V_ref``.
    slip_fraction_laps : float
        Share of the laps spent following another bike.
    slip_reduction : tuple of float
        Range of the relative reduction of h on straights while following.
    mu_amplitude : float
        mu(T)/mu_nominal = 1 + a * tanh((T - T_mu) / dT_mu).
    kz_ratio : float
        Through-thickness over in-plane conductivity.
    ir_lag_s : float — s
        First-order time constant of the IR sensor.
    emissivity_set : float
        Emissivity configured in the pyrometer (the disc's true one is the datasheet's).
    strong : tuple of str
        Names switched to their strong level.
    """

    crown_base_concentration: float
    crown_event_concentration: float
    knee_gain: float
    slip_fraction_laps: float
    slip_reduction: tuple[float, float]
    mu_amplitude: float
    kz_ratio: float
    ir_lag_s: float
    emissivity_set: float
    strong: tuple[str, ...]

    def levels(self) -> dict[str, str]:
        """``{effect name: "mild" | "strong"}`` for every named effect."""
        return {n: ("strong" if n in self.strong else "mild") for n in EFFECT_NAMES}

    def as_dict(self) -> dict[str, object]:
        out = asdict(self)
        out["slip_reduction"] = list(self.slip_reduction)
        out["strong"] = list(self.strong)
        out["levels"] = self.levels()
        return out


_MILD = dict(
    crown_base_concentration=400.0,
    crown_event_concentration=800.0,
    knee_gain=0.04,
    slip_fraction_laps=0.2,
    slip_reduction=(0.04, 0.06),
    mu_amplitude=0.03,
    kz_ratio=0.6,
    ir_lag_s=0.04,
    emissivity_set=0.86,
)

_STRONG = {
    "power_distribution": dict(crown_base_concentration=4.0, crown_event_concentration=60.0),
    "h_speed_knee": dict(knee_gain=0.40),
    "slipstream": dict(slip_fraction_laps=0.5, slip_reduction=(0.25, 0.35)),
    "friction_temperature": dict(mu_amplitude=0.18),
    "thickness_gradient": dict(kz_ratio=0.07),
    "sensor_lag": dict(ir_lag_s=0.35),
    "emissivity_error": dict(emissivity_set=1.0),
}


def make_effects(strong: Iterable[str] = ()) -> Effects:
    """Effects with the named ones at their strong level, the rest mild.

    Raises
    ------
    ConfigError
        On an unknown effect name (the message lists the valid ones).
    """
    names = tuple(dict.fromkeys(s.strip() for s in strong if s.strip()))
    unknown = [n for n in names if n not in EFFECT_NAMES]
    if unknown:
        raise ConfigError(
            f"unknown effect(s) {', '.join(unknown)}; valid effects are: {', '.join(EFFECT_NAMES)}"
        )
    params: dict[str, object] = dict(_MILD)
    for n in EFFECT_NAMES:
        if n in names:
            params.update(_STRONG[n])
    return Effects(**params, strong=tuple(n for n in EFFECT_NAMES if n in names))  # type: ignore[arg-type]
