"""The named unmodelled effects of the simulator and their continuous strengths.

Every effect is always present. Strength 0 is the mild baseline a well-behaved bike
shows anyway, and that baseline itself is drawn per seed from a small realistic range
(so no estimator can tune to one fixed mild level). Strength 1 is the strong level;
values in between (and up to :data:`STRENGTH_MAX`) interpolate each parameter on its
own scale: logarithmic for concentrations, spreads, time constants and conductivities,
linear for gains and fractions. Names are fixed by OUTPUTS.md.

``--effects a=0.7,b`` sets ``a`` to strength 0.7 and ``b`` to 1 (a bare name keeps the
old meaning "strong"); every effect not named stays at strength 0.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields

import numpy as np

from brakethermo.errors import ConfigError

# The names are the output contract's (OUTPUTS.md), shared with the estimator's registry;
# nothing else of the estimator's models reaches the truth model.
from brakethermo.vocabulary import EFFECT_NAMES

STRENGTH_MAX = 1.5

EffectsSpec = Mapping[str, float] | Iterable[str] | str


@dataclass(frozen=True)
class _Param:
    """One strength-driven parameter: its seed-drawn mild range and its strong value.

    ``scale`` ``"log"`` interpolates ``mild * (strong / mild) ** s``; ``"lin"``
    ``mild + s * (strong - mild)``. ``relative`` makes ``strong`` a factor on the mild
    draw (the strong disc is a fraction of this seed's batch value).
    """

    name: str
    mild: tuple[float, float]
    strong: float
    scale: str
    relative: bool = False
    bounds: tuple[float, float] = (-math.inf, math.inf)

    def draw_mild(self, rng: np.random.Generator | None) -> float:
        lo, hi = self.mild
        if self.scale == "log":
            u = 0.5 if rng is None else float(rng.uniform())
            return float(math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo))))
        return 0.5 * (lo + hi) if rng is None else float(rng.uniform(lo, hi))

    def at(self, mild: float, s: float) -> float:
        strong = self.strong * mild if self.relative else self.strong
        if self.scale == "log":
            value = mild * (strong / mild) ** s
        else:
            value = mild + s * (strong - mild)
        return float(min(max(value, self.bounds[0]), self.bounds[1]))


# Per effect, the parameters its strength moves. The strong values are the former
# fixed strong levels (the crown spread and the IR lag are capped where the log scale
# would leave what a disc and a sensor do), except where a real bike differs from the
# old shape:
# friction_temperature reaches mu/mu_nom 0.80 at 150 degC and 1.15 at 600 degC
# (carbon-carbon: a cold deficit larger than the hot gain), and thickness_gradient
# is a physical k_z around the datasheet's 12 W/(m K), the strong disc at 0.4 of it.
_SPECS: dict[str, tuple[_Param, ...]] = {
    "power_distribution": (
        _Param("crown_sigma_base", (0.035, 0.07), 0.5, "log", bounds=(0.0, 1.0)),
        _Param("crown_sigma_event", (0.045, 0.08), 0.22, "log"),
    ),
    "h_speed_knee": (_Param("knee_gain", (0.02, 0.06), 0.40, "lin", bounds=(0.0, 1.0)),),
    "slipstream": (
        _Param("slip_fraction_laps", (0.1, 0.3), 0.5, "lin", bounds=(0.0, 1.0)),
        _Param("slip_reduction", (0.03, 0.07), 0.30, "lin", bounds=(0.0, 0.6)),
    ),
    "friction_temperature": (
        _Param("mu_deficit", (0.02, 0.05), 0.22, "lin", bounds=(0.0, 0.45)),
        _Param("mu_gain", (0.02, 0.05), 0.17, "lin", bounds=(0.0, 0.4)),
        _Param("mu_t_mid", (400.0, 470.0), 380.0, "lin", bounds=(250.0, 550.0)),
        _Param("mu_t_width", (130.0, 180.0), 75.0, "log"),
    ),
    "thickness_gradient": (_Param("k_z", (10.5, 13.5), 0.4, "log", relative=True),),
    "sensor_lag": (_Param("ir_lag_s", (0.03, 0.06), 0.35, "log", bounds=(0.0, 0.8)),),
    "emissivity_error": (_Param("emissivity_divisor", (0.835, 0.875), 1.0, "log"),),
}

# Shape parameters drawn per seed and not moved by any strength.
_SHAPE = (
    _Param("knee_frac", (0.74, 0.86), 0.0, "lin"),
    _Param("knee_exponent", (1.6, 2.4), 0.0, "lin"),
)


@dataclass(frozen=True)
class Effects:
    """Effect parameters of one run (every effect is present; strength 0 = mild).

    Attributes
    ----------
    crown_sigma_base : float
        Spread of the log pad-crown weights between corners (logistic-normal; half of
        it shared by the whole session, half per corner). 0.05 gives weights within a
        few per cent of 1/3, 0.5 about +-0.13.
    crown_sigma_event : float
        Spread of the log crown weights of each braking around its corner's base.
    knee_gain : float
        Relative rise of h at V_ref over the low-speed law, growing as
        ``((V - V_k) / (V_ref - V_k)) ** knee_exponent`` above ``V_k = knee_frac V_ref``.
    knee_frac, knee_exponent : float
        Knee onset over V_ref and growth exponent (drawn per seed).
    slip_fraction_laps : float
        Share of the flying laps spent following another bike.
    slip_reduction : float
        Mean relative reduction of h on a straight while following; each straight of
        each following lap draws its own within +-20 % of it.
    mu_deficit, mu_gain : float
        mu(T)/mu_nom runs from ``1 - mu_deficit`` (cold) to ``1 + mu_gain`` (hot).
    mu_t_mid, mu_t_width : float — degC
        Centre and width of the logistic rise between the two.
    k_z : float — W/(m K)
        Through-thickness conductivity at 400 degC; it follows the in-plane k(T)'s
        temperature dependence.
    ir_lag_s : float — s
        First-order time constant of the IR sensor.
    emissivity_set : float
        Emissivity configured in the pyrometer (the disc's true one is the datasheet's).
    lens_transmission : float
        Transmission of the pyrometer's lens (1 = clean; below 1 only beyond strength 1,
        when the setting is already at its maximum of 1: a dust-fouled lens).
    strengths : tuple of (str, float)
        Strength of every named effect, in :data:`EFFECT_NAMES` order.
    mild : tuple of (str, float)
        This seed's mild (strength-0) value of every strength-driven parameter.
    """

    crown_sigma_base: float
    crown_sigma_event: float
    knee_gain: float
    knee_frac: float
    knee_exponent: float
    slip_fraction_laps: float
    slip_reduction: float
    mu_deficit: float
    mu_gain: float
    mu_t_mid: float
    mu_t_width: float
    k_z: float
    ir_lag_s: float
    emissivity_set: float
    lens_transmission: float
    strengths: tuple[tuple[str, float], ...]
    mild: tuple[tuple[str, float], ...]

    @property
    def strength(self) -> dict[str, float]:
        """``{effect name: strength}`` for every named effect."""
        return dict(self.strengths)

    @property
    def active(self) -> tuple[str, ...]:
        """Names with a strength above 0."""
        return tuple(n for n, s in self.strengths if s > 0.0)

    def params(self) -> dict[str, float]:
        """The physical parameter values of this run."""
        skip = {"strengths", "mild"}
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name not in skip}

    def as_dict(self) -> dict[str, object]:
        return {
            **self.params(),
            "strengths": self.strength,
            "mild": dict(self.mild),
            "active": list(self.active),
        }


def parse_effects(text: str) -> dict[str, float]:
    """``"a=0.7,b"`` -> ``{"a": 0.7, "b": 1.0}``; validated like :func:`strengths_of`.

    Raises
    ------
    ConfigError
        On an unknown name, a strength that is not a number, or one out of range.
    """
    out: dict[str, float] = {}
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        name, sep, value = (p.strip() for p in item.partition("="))
        if not sep:
            out[name] = 1.0
            continue
        try:
            out[name] = float(value)
        except ValueError:
            raise ConfigError(
                f"--effects: strength of {name!r} must be a number, got {value!r}"
                f" (write name=strength, e.g. {name}=0.8)"
            ) from None
    return strengths_of(out)


def strengths_of(effects: EffectsSpec = ()) -> dict[str, float]:
    """Strength of every named effect (in :data:`EFFECT_NAMES` order) from a mapping
    ``name -> strength``, an iterable of names (each at strength 1) or ``"a=0.7,b"``.

    Raises
    ------
    ConfigError
        On an unknown name (the message lists the valid ones) or a strength outside
        ``[0, STRENGTH_MAX]``.
    """
    if isinstance(effects, str):
        return parse_effects(effects)
    if isinstance(effects, Mapping):
        given = {str(k).strip(): float(v) for k, v in effects.items()}
    else:
        given = {str(n).strip(): 1.0 for n in effects if str(n).strip()}
    unknown = [n for n in given if n not in EFFECT_NAMES]
    if unknown:
        raise ConfigError(
            f"unknown effect(s) {', '.join(unknown)}; valid effects are: {', '.join(EFFECT_NAMES)}"
        )
    bad = [f"{n}={s}" for n, s in given.items() if not 0.0 <= s <= STRENGTH_MAX]
    if bad:
        raise ConfigError(
            f"effect strength out of range: {', '.join(bad)}; expected 0 (mild) to"
            f" {STRENGTH_MAX} (1 = strong)"
        )
    return {n: given.get(n, 0.0) for n in EFFECT_NAMES}


def random_strengths(
    rng: np.random.Generator,
    names: Iterable[str] = EFFECT_NAMES,
    low: float = 0.5,
    high: float = 1.3,
) -> dict[str, float]:
    """A realistic strength per named effect for test matrices, uniform in [low, high].

    Rounded to 0.01 so the same session can be re-made from the command line
    (``--effects name=0.87``). Effects not named stay at 0 when passed to
    :class:`~brakethermo.sim.session.SimConfig`.
    """
    if not 0.0 <= low <= high <= STRENGTH_MAX:
        raise ConfigError(f"need 0 <= low <= high <= {STRENGTH_MAX}, got low={low}, high={high}")
    names = tuple(names)
    strengths_of(names)  # validates the names
    return {n: round(float(rng.uniform(low, high)), 2) for n in names}


def make_effects(
    effects: EffectsSpec = (), rng: np.random.Generator | None = None
) -> Effects:
    """Effect parameters at the given strengths.

    Parameters
    ----------
    effects : mapping, iterable of str or str
        See :func:`strengths_of`.
    rng : numpy.random.Generator, optional
        Draws this seed's mild baseline. Every mild value is drawn whatever the
        strengths, in a fixed order, so strengths never shift other draws. Without it
        each mild value is the middle of its range.
    """
    strength = strengths_of(effects)
    mild: dict[str, float] = {}
    values: dict[str, float] = {}
    for p in _SHAPE:
        values[p.name] = p.draw_mild(rng)
    for name in EFFECT_NAMES:
        for p in _SPECS[name]:
            mild[p.name] = p.draw_mild(rng)
            values[p.name] = p.at(mild[p.name], strength[name])
    # Beyond strength 1 the setting stays at the pyrometer's maximum of 1 and the lens
    # transmission carries the rest of the radiance ratio.
    divisor = values.pop("emissivity_divisor")
    values["emissivity_set"] = min(divisor, 1.0)
    values["lens_transmission"] = min(1.0, 1.0 / divisor)
    return Effects(
        **values,  # type: ignore[arg-type]
        strengths=tuple(strength.items()),
        mild=tuple(mild.items()),
    )
