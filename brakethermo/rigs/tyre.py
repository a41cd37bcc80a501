"""Longitudinal tyre friction curves μ(s): Rudd's two-parameter curve, Burckhardt, Magic Formula.

Slip ``s`` is the braking slip ratio (V − ωR)/V: 0 free rolling, 1 locked. Every curve
returns the friction coefficient μ = F_x / F_z (dimensionless, positive in braking) and
broadcasts over its arguments, so a batch of parameter vectors (sigma points, finite
difference stencils) evaluates in one call.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def rudd_mu(s: ArrayLike, mu_p: ArrayLike, s_p: ArrayLike) -> Array:
    """Rudd's two-parameter curve μ(s) = 2 μp sp s / (sp² + s²).

    Parameters
    ----------
    s : array_like — slip ratio, –.
    mu_p : array_like — peak friction coefficient, –.
    s_p : array_like — slip at the peak, –.
    """
    s, mu_p, s_p = np.asarray(s, float), np.asarray(mu_p, float), np.asarray(s_p, float)
    return 2.0 * mu_p * s_p * s / (s_p * s_p + s * s)


def rudd_jacobian(s: ArrayLike, mu_p: float, s_p: float) -> Array:
    """∂μ/∂[μp, sp] of :func:`rudd_mu`, shape (…, 2) (the EKF observation row)."""
    s = np.asarray(s, float)
    d = s_p * s_p + s * s
    d_mu = 2.0 * s_p * s / d
    d_sp = 2.0 * mu_p * s * (s * s - s_p * s_p) / (d * d)
    return np.stack([d_mu, d_sp], axis=-1)


def rudd_hessian(s: float, mu_p: float, s_p: float) -> tuple[float, float, float]:
    """Second derivatives (∂²/∂μp², ∂²/∂sp², ∂²/∂μp∂sp) of :func:`rudd_mu` at one slip."""
    d = s_p * s_p + s * s
    h_mm = 0.0
    h_ms = 2.0 * s * (s * s - s_p * s_p) / (d * d)
    # d/dsp of 2 μp s (s² − sp²) / d²
    h_ss = 2.0 * mu_p * s * (-2.0 * s_p * d - 4.0 * s_p * (s * s - s_p * s_p)) / d**3
    return h_mm, h_ss, h_ms


def burckhardt_mu(s: ArrayLike, c1: ArrayLike, c2: ArrayLike, c3: ArrayLike) -> Array:
    """Burckhardt's curve μ(s) = c1 (1 − exp(−c2 s)) − c3 s.

    Parameters
    ----------
    s : array_like — slip ratio, –.
    c1 : array_like — saturation level, –.
    c2 : array_like — initial-slope shape, –.
    c3 : array_like — post-peak fall per unit slip, –.
    """
    s = np.asarray(s, float)
    return np.asarray(c1) * (1.0 - np.exp(-np.asarray(c2) * s)) - np.asarray(c3) * s


def burckhardt_peak(c1: float, c2: float, c3: float) -> tuple[float, float]:
    """Peak (μ, slip) of :func:`burckhardt_mu`: dμ/ds = c1 c2 e^(−c2 s) − c3 = 0.

    Where the curve rises all the way to s = 1 (c3 ≤ c1 c2 e^(−c2)) the peak is at 1;
    where it never rises (c1 c2 ≤ c3) at 0.
    """
    if c1 * c2 <= c3 or c2 <= 0.0:
        return 0.0, 0.0
    s = float(np.log(c1 * c2 / c3) / c2) if c3 > 0.0 else 1.0
    s = min(s, 1.0)
    return float(burckhardt_mu(s, c1, c2, c3)), s


def magic_formula_mu(
    s: ArrayLike, B: ArrayLike, C: ArrayLike, D: ArrayLike, E: ArrayLike = 0.0
) -> Array:
    """Pacejka's Magic Formula μ(s) = D sin(C atan(B s − E (B s − atan(B s)))).

    Parameters
    ----------
    s : array_like — slip ratio, –.
    B : array_like — stiffness factor, –.
    C : array_like — shape factor, –.
    D : array_like — peak factor (peak μ for 1 < C < 2), –.
    E : array_like — curvature factor, –.
    """
    Bs = np.asarray(B) * np.asarray(s, float)
    return np.asarray(D) * np.sin(
        np.asarray(C) * np.arctan(Bs - np.asarray(E) * (Bs - np.arctan(Bs)))
    )


def magic_formula_peak(B: float, C: float, D: float, E: float = 0.0) -> tuple[float, float]:
    """Peak (μ, slip) of :func:`magic_formula_mu` for 1 < C < 2.

    With E = 0 the peak is where C atan(B s) = π/2, s = tan(π / (2C)) / B, μ = D; with
    E ≠ 0 the argument of atan is solved for the same value numerically (it is monotone
    in s for E < 1).
    """
    if not 1.0 < C < 2.0 or B <= 0.0:
        s_grid = np.linspace(0.0, 1.0, 2001)
        mu = magic_formula_mu(s_grid, B, C, D, E)
        i = int(np.argmax(mu))
        return float(mu[i]), float(s_grid[i])
    target = float(np.tan(np.pi / (2.0 * C)))  # B s − E (B s − atan B s) at the peak
    if E == 0.0:
        return float(D), target / B
    from scipy.optimize import brentq

    def g(x: float) -> float:
        return x - E * (x - np.arctan(x)) - target

    hi = 1.0
    while g(hi) < 0.0 and hi < 1e6:
        hi *= 2.0
    x = brentq(g, 0.0, hi)
    return float(D), float(x / B)


def relaxation_lag(x: ArrayLike, t: ArrayLike, speed: ArrayLike, length_m: float) -> Array:
    """``x`` through a tyre's first-order lag over ``length_m`` of travel.

    The longitudinal force builds up over the relaxation length σ: its time constant is
    σ / V, so the force follows the slip (or the steady curve) with that lag.

    Parameters
    ----------
    x : array_like — the series to lag (slip, –, or μ, –), in time order.
    t : array_like — time, s.
    speed : array_like — carriage speed V, m/s, per sample.
    length_m : float — relaxation length σ, m; 0 (or below a micrometre) is no lag.
    """
    x = np.asarray(x, float)
    if length_m <= 1e-6:
        return x
    t = np.asarray(t, float)
    gain = 1.0 - np.exp(-np.asarray(speed, float) * np.diff(t, prepend=t[0]) / length_m)
    out = np.empty_like(x)
    out[0] = x[0]
    for k in range(1, x.size):
        out[k] = out[k - 1] + gain[k] * (x[k] - out[k - 1])
    return out
