"""The unmodelled effects of OUTPUTS.md as extensions of the disc model.

Each effect is registered once here and read by ``diagnose`` (fit alone, score on
held-out laps, rank), by ``identify-h --with-effect`` (fit jointly with h(V)) and by
``estimate`` (use the fitted values, adapt online what one spot can observe). An
effect names its parameters — bounds, the value at which the effect vanishes, a
Gaussian prior that keeps a fit on few laps near that value, whether the estimator
may adapt it as a random walk — and says where it acts: the braking power, h, the
disc structure or the measurement. How it acts is :mod:`brakethermo.models.disc`'s
job: the extended model evaluates every registered effect from one parameter vector.

The laws are deliberately few-parameter and physical, not shaped after our simulator:

- ``power_distribution``: per braking zone, an inner/outer balance ``b`` and a middle
  share ``m`` of the pad-crown weights (``w_1 e^b, w_2 e^m, w_3 e^-b``, normalised to
  conserve power, eq. 6–8): any split of the power over the three crowns; zones
  identified by lap distance. The mean weights are part of every model (the
  reference fits them), as identify-h does.
- ``h_speed_knee``: ``h · (1 + g u²)``, ``u = (V/V_ref − x_k)/(1 − x_k)`` above the knee
  ``x_k`` = 0.8 (tyre deformation exposes the disc above ~0.8 V_ref).
- ``slipstream``: h on each straight of each lap multiplied by its own factor (a
  latent value per straight, with a prior around 1), a departure from the session's own
  h (``disc_effects.departures``: the fitted straights' geometric mean is 1): following
  another bike changes the cooling air straight by straight, not as a law of speed.
- ``friction_temperature``: braking power × μ(T)/μ_ref with
  ``μ(T)/μ_ref = 1 + β · clip((T − T_m)/ΔT, −1, 1)``, T the contact-band face
  temperature of the previous step, ΔT = 250 °C; parameters β and T_m.
- ``thickness_gradient``: a multiplier of the nominal through-thickness conductivity.
- ``sensor_lag``: a first-order pyrometer ``τ ẏ + y = T_face``.
- ``emissivity_error``: a total-radiation grey-body pyrometer set to the wrong
  emissivity reads ``T_K · r^(1/4)`` with ``r = ε_disc/ε_set`` (temperatures in kelvin):
  the reading follows the radiance ratio, not an additive offset.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from brakethermo.errors import ConfigError
from brakethermo.vocabulary import EFFECT_NAMES

ActsOn = Literal["power", "h", "structure", "measurement"]
Observability = Literal["online", "test-session", "none"]

MU_SPAN_C = 250.0  # degC, half-width of the mu(T) ramp
NO_LAG_S = 0.01  # s: a time constant this short is no lag on the 0.1 s grid
LATENT = "latent"  # marks per-segment parameters whose count depends on the session


@dataclass(frozen=True)
class EffectParam:
    """One parameter of an effect.

    Attributes
    ----------
    name : str
    neutral : float
        Value at which the effect vanishes (the reference model), in ``unit``.
    lower, upper : float
        Bounds, in ``unit``.
    log : bool
        Fitted as ``log(value)`` (positive multipliers and time constants).
    prior_sigma : float or None
        Standard deviation of a Gaussian prior around ``neutral`` in the fitted space
        (log space when ``log``); ``None`` = no prior.
    unit : str
    online_step : float or None
        Random-walk standard deviation per 0.1 s step when ``estimate`` adapts the value
        online from one spot; ``None`` = fixed at the test-session value.
    shape : bool
        A shape parameter (where a ramp sits, not how strong the effect is): its bound is
        no sign that the effect's form misfits the data (:meth:`ExtendedDisc.at_bounds`).
    """

    name: str
    neutral: float
    lower: float
    upper: float
    log: bool = False
    prior_sigma: float | None = None
    unit: str = "-"
    online_step: float | None = None
    shape: bool = False

    def to_fit(self, value: float | np.ndarray) -> np.ndarray:
        """Value (in ``unit``) to the fitted space."""
        v = np.asarray(value, dtype=float)
        return np.log(np.maximum(v, 1e-12)) if self.log else v

    def from_fit(self, p: float | np.ndarray) -> np.ndarray:
        """Fitted space to the value (in ``unit``)."""
        p = np.asarray(p, dtype=float)
        return np.exp(p) if self.log else p

    @property
    def bounds_fit(self) -> tuple[float, float]:
        return float(self.to_fit(self.lower)), float(self.to_fit(self.upper))


@dataclass(frozen=True)
class Effect:
    """A named model extension.

    Attributes
    ----------
    name : str
        One of :data:`EFFECT_NAMES`.
    acts_on : {"power", "h", "structure", "measurement"}
    params : tuple of EffectParam
        Session-independent parameters.
    latent : str or None
        Per-segment latent parameters on top of ``params``: ``"zone"`` (one set per
        braking zone of the lap) or ``"straight"`` (one set per straight of every lap);
        their priors and bounds are those of :attr:`latent_params`.
    latent_params : tuple of EffectParam
    extension : str
        What the model gains, for the report.
    signature : str
        The residual pattern the effect removes (the evidence the diagnosis looks for).
    single_spot : {"online", "test-session", "none"}
        What one race pyrometer can do with it: adapt it online, only use the
        test-session value, or nothing.
    separate_by : str
        The data that tell this effect from look-alikes, and how to get them (what a
        set verdict asks the engineer for).
    """

    name: str
    acts_on: ActsOn
    params: tuple[EffectParam, ...]
    extension: str
    signature: str
    single_spot: Observability
    latent: Literal["zone", "straight"] | None = None
    latent_params: tuple[EffectParam, ...] = ()
    separate_by: str = ""


EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "power_distribution", "power",
            (),
            "per braking zone, the split of the power over the three pad crowns (inner/outer"
            " balance and middle share; the mean weights belong to the reference: every"
            " disc needs them)",
            "inner and outer spots of opposite sign under braking, repeating by braking zone",
            "test-session",
            latent="zone",
            latent_params=(EffectParam("zone_balance", 0.0, -1.5, 1.5, prior_sigma=0.8),
                           EffectParam("zone_middle", 0.0, -1.5, 1.5, prior_sigma=0.8)),
            separate_by=("the inner and outer spots (1 and 4) under braking, braking zone by"
                         " braking zone: more laps per zone, or a contact thermocouple at "
                         "the inner and outer pad radius"),
        ),
        Effect(
            "h_speed_knee", "h",
            (EffectParam("gain", 0.0, -0.5, 3.0, prior_sigma=1.0),),
            "h multiplied by 1 + g u^2 above 0.8 V_ref (u = 0 at the knee, 1 at V_ref)",
            "cooling only, at high speed: the model stays too hot on the fastest straights",
            "test-session",
            separate_by=("cooling on the fastest straights against the slow ones: laps with "
                         "long straights above 0.8 V_ref, or a run at steady top speed with "
                         "the brakes off"),
        ),
        Effect(
            "slipstream", "h",
            (),
            "h on each straight of each lap multiplied by its own factor, a departure from"
            " the session's own h (following another bike changes the cooling air straight"
            " by straight)",
            "cooling only, lap to lap: the same straight cools faster on some laps than on"
            " others, all spots alike",
            "online",
            latent="straight",
            latent_params=(EffectParam("straight_factor", 1.0, 0.4, 1.6, log=True,
                                       prior_sigma=0.2, online_step=0.01),),
            separate_by=("laps run alone against laps in a group: the same straight cools "
                         "differently when following another bike"),
        ),
        Effect(
            "friction_temperature", "power",
            (EffectParam("beta", 0.0, -0.6, 0.6, prior_sigma=0.3),
             EffectParam("t_mid", 400.0, 150.0, 700.0, prior_sigma=150.0, unit="degC",
                         shape=True)),
            "braking power x mu(T)/mu_ref = 1 + beta clip((T - T_m)/250 degC, -1, 1), T the"
            " contact-band face temperature",
            "braking only, growing with disc temperature: too little heat in hot stops, too"
            " much in cold ones",
            "test-session",
            separate_by=("stops at different disc temperatures: the cold first stops of a "
                         "run against hot laps, or a brake-torque (strain) measurement"),
        ),
        Effect(
            "thickness_gradient", "structure",
            (EffectParam("kz_factor", 1.0, 0.1, 5.0, log=True, prior_sigma=1.0),),
            "through-thickness conductivity = factor x the datasheet's nominal k_z",
            "face hotter than the model in braking and cooler right after release (the skin"
            " heats and cools faster than the bulk), every spot alike",
            "test-session",
            separate_by=("the seconds after each release, when the skin cools faster than "
                         "the bulk: a cool-down run with the bike at rest, or a second "
                         "pyrometer"),
        ),
        Effect(
            "sensor_lag", "measurement",
            (EffectParam("tau_s", NO_LAG_S, NO_LAG_S, 3.0, log=True, prior_sigma=2.0,
                         unit="s"),),
            "first-order pyrometer tau dy/dt + y = T_face",
            "residual proportional to dT/dt: reading low while heating, high while cooling",
            "test-session",
            separate_by=("sharp stops against slow cooling: the reading's delay where the "
                         "temperature moves fastest, or a second, faster pyrometer"),
        ),
        Effect(
            "emissivity_error", "measurement",
            (EffectParam("ratio", 1.0, 0.6, 1.5, log=True, prior_sigma=0.2),),
            "total-radiation pyrometer set to the wrong emissivity: reading ="
            " T_K (eps_disc/eps_set)^(1/4)",
            "bias growing with absolute temperature, in every phase and at every spot",
            "none",
            separate_by=("the reading error against absolute temperature, hot and cold "
                         "alike: a contact thermocouple on a cold and on a hot disc, or a "
                         "pyrometer of known emissivity"),
        ),
    )
}


def parse_effects(text: str | None) -> tuple[str, ...]:
    """Effect names from ``all``, ``none``/empty or a comma-separated list.

    Raises
    ------
    ConfigError
        An unknown name (the message lists the valid ones).
    """
    if text is None or text.strip().lower() in ("", "all"):
        return EFFECT_NAMES
    if text.strip().lower() == "none":
        return ()
    names = tuple(dict.fromkeys(s.strip() for s in text.split(",") if s.strip()))
    words = [n for n in names if n.lower() in ("all", "none", "auto")]
    if words and len(names) == 1:
        raise ConfigError(f"'{names[0]}' is not taken here; give 'all', 'none' or effect"
                          f" names: {', '.join(EFFECT_NAMES)}")
    if words:
        raise ConfigError(f"'{words[0]}' stands alone, not in a list of effects (got"
                          f" '{text}'); give it alone, or name the effects")
    # NAME=STRENGTH is simulate's syntax: here an effect is fitted, its strength found
    strengths = [n for n in names if "=" in n and n.split("=", 1)[0].strip() in EFFECTS]
    if strengths:
        bare = ", ".join(n.split("=", 1)[0].strip() for n in strengths)
        raise ConfigError(f"'{strengths[0]}': strengths are not taken here (the fit finds"
                          f" them; NAME=STRENGTH is `simulate --effects`); name the effect"
                          f" alone: {bare}")
    unknown = [n for n in names if n not in EFFECTS]
    if unknown:
        raise ConfigError(
            f"unknown effect(s) {', '.join(unknown)}; valid effects are: "
            f"{', '.join(EFFECT_NAMES)}, or alone 'all' or 'none'"
        )
    return names


def mu_ratio(t_c: np.ndarray, beta: np.ndarray, t_mid_c: np.ndarray) -> np.ndarray:
    """mu(T)/mu_ref of ``friction_temperature`` (module docstring), dimensionless."""
    return 1.0 + beta * np.clip((t_c - t_mid_c) / MU_SPAN_C, -1.0, 1.0)


def knee_factor(v_mps: np.ndarray, v_ref: float, knee: float, gain: np.ndarray) -> np.ndarray:
    """``1 + g u²`` above the knee, 1 below (``h_speed_knee``)."""
    u = np.clip((np.abs(v_mps) / v_ref - knee) / (1.0 - knee), 0.0, None)
    return 1.0 + np.multiply.outer(gain, u * u)


def pyrometer_reading(t_c: np.ndarray, ratio: np.ndarray) -> np.ndarray:
    """Reading of a grey-body pyrometer with ``ratio = eps_disc/eps_set``, degC."""
    return (t_c + 273.15) * ratio**0.25 - 273.15


def true_from_reading(y_c: np.ndarray, ratio: float) -> np.ndarray:
    """Inverse of :func:`pyrometer_reading`: the face temperature behind a reading, degC."""
    return (y_c + 273.15) / ratio**0.25 - 273.15


def lag_alpha(tau_s: np.ndarray, dt: float) -> np.ndarray:
    """Discrete gain of the first-order sensor over one step, ``1 − exp(−dt/τ)``.

    Exactly 1 (no lag) for ``τ <= NO_LAG_S``, so the neutral effect is the ideal sensor.
    """
    tau = np.asarray(tau_s, dtype=float)
    return np.where(tau <= NO_LAG_S * (1.0 + 1e-9), 1.0,
                    -np.expm1(-dt / np.maximum(tau, NO_LAG_S)))
