"""Clamp force of an electro-mechanical caliper from its resolver and motor current.

The three estimators of Saric & Bab-Hadiashar (2007), as pure functions of logged
samples on a uniform grid of step ``ts``:

- the dynamic stiffness model, eq. 6: F(k) = α3 θ³ + α2 θ² + α1 θ + α4 + α0 F(k−1),
  a cubic in the motor angle θ driving a first-order autoregression (the constant α4
  places the contact point, which moves with pad wear);
- the torque balance, eq. 7: F(k) = (Km I(k) − J θ̈(k) − A sgn ω(k) − T0) / (γ + μ sgn ω(k)),
  θ̈ from the second difference of the resolver angle, ω from its first difference,
  Coulomb friction μ γ-proportional to the load plus an offset A; T0 is a constant
  torque (a current-sensor offset), zero in the paper;
- the non-recursive maximum-likelihood fusion of the two, eq. 8.

Forces are in N inside, angles in rad, currents in A, torques in N m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.signal import lfilter, savgol_filter

Array = NDArray[np.float64]


DECONVOLVE_WINDOW_S = 0.011  # s, derivative window of :func:`sensor_delagged`


def stiffness_regressors(theta: Array) -> Array:
    """Columns [θ³, θ², θ, 1] of the input part of eq. 6, shape (K, 4)."""
    theta = np.asarray(theta, dtype=float)
    return np.stack([theta**3, theta**2, theta, np.ones_like(theta)], axis=1)


def stiffness_input(theta: Array, beta: Array) -> Array:
    """u(k) = α3 θ³ + α2 θ² + α1 θ + α4 (eq. 12 plus the constant), N; beta = [α3, α2, α1, α4]."""
    return stiffness_regressors(theta) @ np.asarray(beta, dtype=float)


def dynamic_stiffness(
    theta: Array, alpha0: float, beta: Array, F_init: float | None = None
) -> Array:
    """Run eq. 6 open loop: F(k) = α0 F(k−1) + u(k), N.

    Parameters
    ----------
    theta : ndarray (K,) — motor angle, rad.
    alpha0 : float — autoregressive coefficient, –.
    beta : ndarray (4,) — [α3 N/rad³, α2 N/rad², α1 N/rad, α4 N].
    F_init : float, optional — F(−1), N; default the steady state u(0) / (1 − α0).
    """
    u = stiffness_input(theta, beta)
    if F_init is None:
        F_init = u[0] / (1.0 - alpha0)
    zi = np.array([alpha0 * F_init])
    F, _ = lfilter([1.0], [1.0, -alpha0], u, zi=zi)
    return F


def motor_rates(theta: Array, ts: float, window: int = 1) -> tuple[Array, Array]:
    """Motor speed ω (rad/s) and acceleration θ̈ (rad/s²) from the resolver angle.

    ``window = 1``: the backward differences of eq. 7, ω(k) = (θ(k) − θ(k−1))/ts,
    θ̈(k) = (θ(k) − 2θ(k−1) + θ(k−2))/ts², the first two samples repeating the first
    available difference. ``window > 1`` (odd): Savitzky-Golay derivatives (cubic over
    ``window`` samples, centred): offline, the second difference of a quantised angle
    is mostly quantisation noise (lsb·√6/ts²), which a centred fit averages out.
    """
    theta = np.asarray(theta, dtype=float)
    if window > 1:
        n = min(window, theta.size - (1 - theta.size % 2))
        if n >= 5:
            omega = savgol_filter(theta, n, 3, deriv=1, delta=ts, mode="interp")
            acc = savgol_filter(theta, n, 3, deriv=2, delta=ts, mode="interp")
            return omega, acc
    omega = np.empty_like(theta)
    acc = np.zeros_like(theta)
    omega[1:] = np.diff(theta) / ts
    omega[0] = omega[1] if theta.size > 1 else 0.0
    if theta.size > 2:
        acc[2:] = np.diff(theta, 2) / ts**2
        acc[:2] = acc[2]
    return omega, acc


@dataclass(frozen=True)
class TorqueBalance:
    """Parameters of eq. 7 per unit motor current (the motor constant Km is not observable).

    Attributes
    ----------
    gamma : float — γ/Km, A/N: current per newton of clamp force.
    inertia : float — J/Km, A s²/rad.
    mu : float — μ/Km, A/N: load-proportional Coulomb friction.
    offset : float — A/Km, A: load-independent Coulomb friction.
    bias : float — T0/Km, A: constant current offset.
    omega_s : float — speed band of the friction sign, rad/s: sgn ω is replaced by
        tanh(ω / ω_s), 0 keeping the paper's sgn (see :func:`friction_sign`).
    """

    gamma: float
    inertia: float
    mu: float
    offset: float
    bias: float
    omega_s: float = 0.0


def friction_sign(omega: Array, omega_s: float) -> Array:
    """sgn ω of eq. 7, or tanh(ω / ω_s) for ω_s > 0.

    Real friction does not switch sign in one sample at standstill, and a speed from a
    quantised angle dithers around zero there; a band of a fraction of a rad/s, chosen
    on the training session, follows the reversal instead of flipping on noise.
    """
    return np.sign(omega) if omega_s <= 0.0 else np.tanh(omega / omega_s)


def torque_balance_force(
    current: Array,
    theta: Array,
    ts: float,
    p: TorqueBalance,
    window: int = 1,
    *,
    rates: tuple[Array, Array] | None = None,
) -> Array:
    """Clamp force of eq. 7, N, from the motor current (A) and angle (rad) on a grid of step
    ts (s); ``window`` as :func:`motor_rates`, whose result ``rates`` may be passed in."""
    omega, acc = motor_rates(theta, ts, window) if rates is None else rates
    sgn = friction_sign(omega, p.omega_s)
    return (np.asarray(current, float) - p.inertia * acc - p.offset * sgn - p.bias) / (
        p.gamma + p.mu * sgn
    )


def sensor_delagged(F: Array, lag_s: float, ts: float) -> Array:
    """The force behind a first-order sensor of time constant τ: F + τ dF/dt, N.

    The inverse of the sensor's lag (τ dy/dt + y = F), with the derivative a
    Savitzky-Golay cubic over about :data:`DECONVOLVE_WINDOW_S` (at least 5 samples);
    the derivative's noise, independent of any estimate, adds alike to every estimate's
    error against the result. Each stretch between gaps is differentiated on its own,
    and a stretch shorter than the window keeps ``np.gradient``'s differences.

    Parameters
    ----------
    F : ndarray (K,) — sensor force, N (NaN in gaps).
    lag_s : float — s, the sensor's time constant τ (0: ``F`` returned as it is).
    ts : float — s, sample time.
    """
    F = np.asarray(F, dtype=float)
    if lag_s <= 0.0:
        return F
    n = max(5, round(DECONVOLVE_WINDOW_S / ts) | 1)
    out = np.full_like(F, np.nan)
    ok = np.isfinite(F)
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        seg = F[a:b]
        if seg.size >= n:
            d = savgol_filter(seg, n, 3, deriv=1, delta=ts, mode="interp")
        elif seg.size >= 2:
            d = np.gradient(seg, ts)
        else:
            continue
        out[a:b] = seg + lag_s * d
    return out


def fit_torque_balance(
    current: Array,
    theta: Array,
    ts: float,
    F: Array,
    window: int = 1,
    omega_s: float = 0.0,
    *,
    rows: NDArray[np.bool_] | None = None,
    rates: tuple[Array, Array] | None = None,
) -> TorqueBalance:
    """Least squares of eq. 7 rearranged linearly: I = (γ + μ sgn ω) F + J θ̈ + A sgn ω + T0.

    Parameters
    ----------
    current : ndarray (K,) — motor current, A.
    theta : ndarray (K,) — motor angle, rad.
    ts : float — sample time, s.
    F : ndarray (K,) — clamp force from the sensor, N.
    window : int — derivative window of :func:`motor_rates`.
    omega_s : float — friction sign band of :func:`friction_sign`, rad/s.
    rows : ndarray (K,) of bool, optional — samples to fit on (default all).
    rates : (ndarray, ndarray), optional — :func:`motor_rates` of ``theta``, if known.
    """
    omega, acc = motor_rates(theta, ts, window) if rates is None else rates
    sgn = friction_sign(omega, omega_s)
    X = np.stack([F, acc, F * sgn, sgn, np.ones_like(F)], axis=1)
    ok = np.isfinite(X).all(axis=1) & np.isfinite(current)
    if rows is not None:
        ok &= rows
    scale = np.maximum(np.abs(X[ok]).max(axis=0), 1e-300)
    coef = np.linalg.lstsq(X[ok] / scale, np.asarray(current)[ok], rcond=None)[0] / scale
    return TorqueBalance(*(float(c) for c in coef), omega_s=omega_s)


@dataclass(frozen=True)
class DynamicStiffness:
    """Parameters of eq. 6.

    Attributes
    ----------
    alpha0 : float — autoregressive coefficient, –.
    beta : tuple of float — (α3 N/rad³, α2 N/rad², α1 N/rad, α4 N).
    """

    alpha0: float
    beta: tuple[float, float, float, float]

    def simulate(self, theta: Array, F_init: float | None = None) -> Array:
        """Open-loop force of eq. 6, N."""
        return dynamic_stiffness(theta, self.alpha0, np.array(self.beta), F_init)

    def inputs(self, theta: Array) -> Array:
        """u(k) of eq. 12 (with the constant α4), N."""
        return stiffness_input(theta, np.array(self.beta))


def fit_dynamic_stiffness(
    theta: Array, F: Array, ts: float, tau0_s: float = 0.02
) -> DynamicStiffness:
    """Least squares of eq. 6 on the simulation (output) error, started from the static cubic.

    An equation-error fit with the sensor's F(k−1) as regressor gives α0 → 1 at kHz rates
    (the previous sample predicts the next almost perfectly) and a model useless without
    the sensor; minimising the open-loop error instead fits what the estimator uses.

    Parameters
    ----------
    theta : ndarray (K,) — motor angle, rad.
    F : ndarray (K,) — clamp force from the sensor, N.
    ts : float — sample time, s.
    tau0_s : float — starting time constant of the autoregression, s.
    """
    theta, F = np.asarray(theta, float), np.asarray(F, float)
    Phi = stiffness_regressors(theta)
    col = np.maximum(np.abs(Phi).max(axis=0), 1e-300)
    static = np.linalg.lstsq(Phi / col, F, rcond=None)[0] / col
    a0 = float(np.exp(-ts / tau0_s))

    # parameters: p = [log(ts / (1 − α0)), static cubic]; F_ss = Φ·static
    def residual(p: Array) -> Array:
        alpha0 = 1.0 - ts * np.exp(-p[0])
        return dynamic_stiffness(theta, alpha0, (1.0 - alpha0) * p[1:]) - F

    p0 = np.concatenate([[np.log(ts / (1.0 - a0))], static])
    x_scale = np.concatenate([[1.0], 1.0 / col])
    sol = least_squares(residual, p0, x_scale=x_scale, method="lm")
    if sol.x[0] < np.log(ts):
        # alpha0 < 0: a mode that flips sign every sample, which a force that follows the
        # angle without a lag of its own (a de-lagged sensor) leaves unidentified; the
        # physical range is a relaxation, 0 <= alpha0 < 1
        lo = np.r_[np.log(ts), np.full(static.size, -np.inf)]
        start = np.r_[np.log(ts) + 1e-6, static]
        sol = least_squares(residual, start, x_scale=x_scale, method="trf",
                            bounds=(lo, np.full(lo.size, np.inf)))
    alpha0 = float(1.0 - ts * np.exp(-sol.x[0]))
    beta = tuple(float(b) for b in (1.0 - alpha0) * sol.x[1:])
    return DynamicStiffness(alpha0, beta)  # type: ignore[arg-type]


def ml_fusion(F_ds: Array, F_tb: Array, sigma_ds: float, sigma_tb: float) -> Array:
    """Eq. 8: F = F_ds + σds² / (σds² + σtb²) (F_tb − F_ds), N."""
    w = sigma_ds**2 / (sigma_ds**2 + sigma_tb**2)
    return F_ds + w * (F_tb - F_ds)
