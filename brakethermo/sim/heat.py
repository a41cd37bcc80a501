"""Heat exchange laws of the truth model: h(V), mu(T), pad-crown power distribution."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class HLaw:
    """True convection law of the disc face, W/(m^2 K).

    ``h(V) = h0 + a * V^n`` (V in m/s), times ``1 + g * x^p`` with
    ``x = (V - V_k) / (V_ref - V_k)`` above the knee ``V_k = knee_frac * V_ref``
    (effect ``h_speed_knee``: gain g, onset and exponent p drawn per seed). The rims
    see ``inner_factor`` and ``outer_factor`` times the face value.
    """

    h0: float = 25.0
    a: float = 4.0
    n: float = 0.8
    inner_factor: float = 0.6
    outer_factor: float = 1.3

    def face(
        self,
        v: np.ndarray,
        v_ref: float,
        knee_gain: float,
        knee_frac: float = 0.8,
        knee_exponent: float = 2.0,
    ) -> np.ndarray:
        """Face h at speed ``v`` (m/s), W/(m^2 K)."""
        v = np.maximum(np.asarray(v, dtype=float), 0.0)
        v_k = knee_frac * v_ref
        x = np.maximum(v - v_k, 0.0) / (v_ref - v_k)
        return (self.h0 + self.a * v**self.n) * (1.0 + knee_gain * x**knee_exponent)

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class MuLaw:
    """Friction coefficient over its nominal value against rubbed-face temperature.

    ``mu/mu_nom = 1 - deficit + (deficit + gain) / (1 + exp(-(T - t_mid) / t_width))``:
    monotone, from a cold deficit to a hot gain of different sizes (carbon-carbon grips
    more hot). The strong law gives 0.80 at 150 degC and 1.15 at 600 degC.
    """

    deficit: float
    gain: float
    t_mid: float
    t_width: float

    def ratio(self, t_face: np.ndarray) -> np.ndarray:
        x = (np.asarray(t_face, dtype=float) - self.t_mid) / self.t_width
        return 1.0 - self.deficit + (self.deficit + self.gain) / (1.0 + np.exp(-x))


def crown_overlap(r_edges: np.ndarray, crown_edges: np.ndarray) -> np.ndarray:
    """Share of each radial cell's face area lying in each pad crown, shape (nr, 3)."""
    lo = np.maximum(r_edges[:-1, None], crown_edges[None, :-1])
    hi = np.minimum(r_edges[1:, None], crown_edges[None, 1:])
    overlap = np.pi * np.maximum(hi * hi - lo * lo, 0.0) * (hi > lo)
    return overlap / (np.pi * np.diff(r_edges**2))[:, None]


def crown_weights(
    n_laps: int,
    n_corners: int,
    sigma_base: float,
    sigma_event: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Pad-crown power weights w_1..w_3 (sum 1) of every braking, shape (n_laps, n_corners, 3).

    Logistic-normal: ``log w = sigma_base (g + z_corner) / sqrt 2 + sigma_event z_event``
    with standard normal ``g`` shared by the session (how this caliper and pad set load
    the crowns), ``z_corner`` per corner (how the rider loads the pads there) and
    ``z_event`` per braking. The normal draws do not depend on the spreads, so a
    stronger effect scales the same pattern.
    """
    g = rng.standard_normal(3)
    z_corner = rng.standard_normal((n_corners, 3))
    z_event = rng.standard_normal((n_laps, n_corners, 3))
    log_w = sigma_base * (g + z_corner)[None] / np.sqrt(2.0) + sigma_event * z_event
    w = np.exp(log_w - log_w.max(axis=-1, keepdims=True))
    return w / w.sum(axis=-1, keepdims=True)


def air_convection_factor(t_new_c: float, t_ref_c: float, exponent: float) -> float:
    """Change of a forced-convection coefficient with the air temperature, dimensionless.

    ``Nu = C Re^m Pr^n`` at one speed and length gives ``h ∝ k (ρ/μ)^m`` (Pr of air
    hardly changes): density from the ideal gas at one pressure, viscosity ``μ`` and
    conductivity ``k`` of air from Sutherland's law (S = 110.4 K and 194 K).
    """
    def props(t_c: float) -> float:
        T = t_c + 273.15
        rho = 1.0 / T
        mu = T**1.5 / (T + 110.4)
        k = T**1.5 / (T + 194.0)
        return k * (rho / mu) ** exponent

    return props(t_new_c) / props(t_ref_c)

