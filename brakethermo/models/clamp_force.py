"""State-space models of the clamp-force estimator (Saric & Bab-Hadiashar 2007, §3).

The paper's scalar Kalman filter: the dynamic stiffness model (eq. 6) is the process,
F(k) = α0 F(k−1) + B u(k) with B u(k) the cubic in the motor angle (eq. 12), and the
torque balance (eq. 7) is the measurement, z(k) = F(k) + v (H = 1, eq. 13); Q and R are
the squared training RMSEs of the two models (constant), P(0) = Q.

Beyond the paper, the adaptive variant adds a random-walk stiffness factor s,
F(k) = α0 F(k−1) + s(k) u(k), s(k) = s(k−1) + w: a two-state filter linear in the state
for a known input, whose transition [[α0, u(k)], [0, 1]] varies with the motor angle.
Pads that soften as they heat (or stiffen with wear) pull s away from 1, and the torque
balance, which does not depend on the pads, tells the filter by how much.

The filter the tool reports (``kf``) is the paper's scalar filter with its process
noise matched to the innovations (covariance matching, Mehra 1972): over a sliding
window the innovations' mean square ``C_ν`` should equal ``α0² P + Q + R``; when it
exceeds that — the stiffness model has drifted from the pads (heat, wear) — the step's
``Q`` is raised to ``C_ν − α0² P − R``, so the fusion leans on the torque balance
exactly as much as the process model has lost, and never below the trained ``Q``; an
excess under :data:`MATCH_EXCESS` is the scatter of a model that holds and changes nothing.
Which of the two filters is reported is decided by the session itself: the matched one
only where the fixed filter's mean NIS exceeds :data:`NIS_LIMIT` (its innovations larger
than its noise settings admit: the pads are not the trained ones), else the fixed one. The
paper's fixed-Q filter stays as ``kf_paper``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from brakethermo.errors import ConfigError
from brakethermo.estimation.kf import kalman_filter_tv
from brakethermo.rigs.emb import (
    DynamicStiffness,
    TorqueBalance,
    fit_dynamic_stiffness,
    fit_torque_balance,
    ml_fusion,
    motor_rates,
    rmse,
    torque_balance_force,
)

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ClampForceModels:
    """The two trained models and their training RMSEs (σ of paper §3).

    Attributes
    ----------
    stiffness : DynamicStiffness — eq. 6.
    torque : TorqueBalance — eq. 7.
    sigma_ds : float — training RMSE of eq. 6, open loop, N (√Q).
    sigma_tb : float — training RMSE of eq. 7, N (√R).
    ts : float — sample time the models were fitted at, s.
    window : int — derivative window of the motor rates in eq. 7 (1 = the paper's
        backward differences), chosen by the training RMSE.
    """

    stiffness: DynamicStiffness
    torque: TorqueBalance
    sigma_ds: float
    sigma_tb: float
    ts: float
    window: int = 1


# Candidate derivative windows for eq. 7, samples (1 = the paper's differences), and
# friction sign bands, rad/s (0 = the paper's sgn).
WINDOWS = (1, 5, 7, 9, 11, 15, 21)
SIGN_BANDS = (0.0, 0.05, 0.1, 0.2, 0.5, 1.0)
CV_BLOCK_S = 2.0  # s, blocks of the two-fold cross-validation of eq. 7's choices


def train(
    theta: Array,
    current: Array,
    F: Array,
    ts: float,
    *,
    structure: ClampForceModels | None = None,
) -> ClampForceModels:
    """Fit eq. 6 and eq. 7 by least squares on a session with the clamp-force sensor.

    Parameters
    ----------
    theta : ndarray (K,) — motor angle, rad.
    current : ndarray (K,) — motor current, A.
    F : ndarray (K,) — clamp-force sensor, N.
    ts : float — sample time, s.
    structure : ClampForceModels, optional — re-training (wear): keep its derivative
        window and friction sign band, which belong to the drive and the log rather
        than to the pads, and refit the parameters only. A short re-training session
        chooses them less reliably than the full training one.

    The derivative window and the friction sign band of eq. 7 are the pair of
    :data:`WINDOWS` x :data:`SIGN_BANDS` with the smallest cross-validated error: fitted
    on alternate blocks of :data:`CV_BLOCK_S` seconds and scored on the others, both
    ways (the in-sample RMSE of a 20 s re-training session picks noise). The paper's
    differences and sgn are the first candidates. Then eq. 7 is refitted on all samples.
    """
    ds = fit_dynamic_stiffness(theta, F, ts)
    sigma_ds = rmse(ds.simulate(theta), F)
    if structure is None:
        fold = (np.arange(theta.size) * ts // CV_BLOCK_S).astype(int) % 2
        omega_acc = {w: motor_rates(theta, ts, w) for w in WINDOWS}

        def cv_score(window: int, band: float) -> float:
            err = []
            for j in (0, 1):
                tb = fit_torque_balance(
                    current, theta, ts, F, window, band, rows=fold == j, rates=omega_acc[window]
                )
                F_tb = torque_balance_force(current, theta, ts, tb, window, rates=omega_acc[window])
                err.append((F_tb - F)[fold != j])
            return float(np.sqrt(np.mean(np.concatenate(err) ** 2)))

        # the first pair with the smallest score, the paper's choices first
        window, band = min(
            ((w, b) for w in WINDOWS for b in SIGN_BANDS), key=lambda wb: cv_score(*wb)
        )
    else:
        window, band = structure.window, structure.torque.omega_s
        omega_acc = {window: motor_rates(theta, ts, window)}
    tb = fit_torque_balance(current, theta, ts, F, window, band, rates=omega_acc[window])
    sigma_tb = rmse(
        torque_balance_force(current, theta, ts, tb, window, rates=omega_acc[window]), F
    )
    return ClampForceModels(ds, tb, sigma_ds, sigma_tb, ts, window)


MATCH_WINDOW_S = 0.5  # s, window of the innovations' mean square (covariance matching)
NIS_LIMIT = 1.5  # mean NIS of the fixed filter above which its model no longer holds
MATCH_EXCESS = 3.0  # the mean square must exceed its expectation this much: a model gap,
#                     not the autocorrelated scatter of a model that holds


def matched_scalar_kf(alpha: float, b: Array, z: Array, Q: float, R: float, x0: float,
                      window: int) -> tuple[Array, Array, Array]:
    """Scalar KF ``x(k+1) = α x(k) + b(k) + w``, ``z = x + v``, Q matched to innovations.

    Parameters
    ----------
    alpha : float — transition.
    b : ndarray (K,) — input term of step ``k -> k+1``, N.
    z : ndarray (K,) — measurements, N (NaN = predict only).
    Q, R : float — trained process and measurement variances, N².
    x0 : float — initial state, N; ``P(0) = Q``.
    window : int — samples of the innovations' moving mean square.

    Returns
    -------
    x, std, q_used, loglik : ndarray (K,) — posterior mean and 1-sigma, N; the step's Q,
        N²; the log-likelihood of each measurement before it is used.
    """
    K = z.size
    x_out, s_out, q_out = np.empty(K), np.empty(K), np.empty(K)
    ll = np.zeros(K)
    x, P = x0, Q
    buf = np.zeros(max(window, 1))
    acc, n = 0.0, 0
    for k in range(K):
        if k > 0:
            P_prev = P
            c_nu = acc / n if n else 0.0
            expected = alpha * alpha * P_prev + Q + R
            q = (max(Q, c_nu - alpha * alpha * P_prev - R)
                 if n == buf.size and c_nu > MATCH_EXCESS * expected else Q)
            x = alpha * x + b[k - 1]
            P = alpha * alpha * P_prev + q
        else:
            q = Q
        if np.isfinite(z[k]):
            nu = z[k] - x
            S = P + R
            ll[k] = -0.5 * (np.log(2.0 * np.pi * S) + nu * nu / S)
            G = P / S
            x = x + G * nu
            P = (1.0 - G) * P
            j = k % buf.size
            acc += nu * nu - buf[j]
            buf[j] = nu * nu
            n = min(n + 1, buf.size)
        x_out[k], s_out[k], q_out[k] = x, np.sqrt(P), q
    return x_out, s_out, q_out, ll


@dataclass(frozen=True)
class ClampForceEstimates:
    """Every estimate of one session, N (factor –).

    Attributes
    ----------
    kf, kf_std : ndarray — the paper's Kalman filter (eq. 9-13) with Q matched to its
        innovations (module docstring), posterior mean and std.
    kf_paper : ndarray — the paper's filter with its fixed Q.
    kf_matched : bool — whether ``kf`` is the matched filter (else the fixed one).
    kf_paper_nis : float — mean NIS of the fixed filter on this session (1 = consistent).
    ml_fusion : ndarray — eq. 8.
    stiffness : ndarray — eq. 6 open loop.
    torque_balance : ndarray — eq. 7.
    adaptive, adaptive_std : ndarray — KF with the random-walk stiffness factor.
    stiffness_factor, stiffness_factor_std : ndarray — its factor s.
    """

    kf: Array
    kf_std: Array
    kf_paper: Array
    kf_matched: bool
    kf_paper_nis: float
    ml_fusion: Array
    stiffness: Array
    torque_balance: Array
    adaptive: Array
    adaptive_std: Array
    stiffness_factor: Array
    stiffness_factor_std: Array


def estimate(
    models: ClampForceModels,
    theta: Array,
    current: Array,
    ts: float,
    *,
    factor_walk: float = 0.02,
) -> ClampForceEstimates:
    """Run all estimators on one session (no clamp-force sensor needed).

    Parameters
    ----------
    models : ClampForceModels
    theta : ndarray (K,) — motor angle, rad.
    current : ndarray (K,) — motor current, A.
    ts : float — sample time, s; must match the training.
    factor_walk : float — random-walk intensity of the stiffness factor, 1/√s.
    """
    if not np.isclose(ts, models.ts, rtol=1e-3):
        raise ConfigError(
            f"the session is logged every {ts * 1e3:g} ms but the models were trained at"
            f" {models.ts * 1e3:g} ms; train on a session logged at the same rate"
        )
    ds = models.stiffness
    F_ds = ds.simulate(theta)
    F_tb = torque_balance_force(current, theta, ts, models.torque, models.window)
    F_ml = ml_fusion(F_ds, F_tb, models.sigma_ds, models.sigma_tb)
    u = ds.inputs(theta)
    K = theta.size
    Q, R = models.sigma_ds**2, models.sigma_tb**2
    y = F_tb[:, None]

    # paper's scalar filter: x(k+1) = α0 x(k) + u(k+1)  (eq. 6, 12), z = x + v (eq. 13)
    b = np.zeros((K, 1))
    b[:-1, 0] = u[1:]
    res = kalman_filter_tv(
        np.array([[ds.alpha0]]),
        np.array([[Q]]),
        np.eye(1),
        np.array([[R]]),
        np.array([F_ds[0]]),
        np.array([[Q]]),
        y,
        b,
    )
    kf_paper = res.x_filt[:, 0]
    kf, kf_std, _, _ = matched_scalar_kf(ds.alpha0, b[:, 0], F_tb, Q, R, float(F_ds[0]),
                                          max(1, round(MATCH_WINDOW_S / ts)))
    # the session decides (no force sensor needed): the matched filter only where the
    # fixed one is over-confident, its innovations larger than its noise settings admit
    nu = F_tb - res.x_pred[:, 0]
    nis = float(np.nanmean(nu**2 / (res.P_pred[:, 0, 0] + R)))
    matched = nis > NIS_LIMIT
    if not matched:
        kf, kf_std = kf_paper, np.sqrt(res.P_filt[:, 0, 0])

    # adaptive: state [F, s], transition [[α0, u(k+1)], [0, 1]]
    A = np.zeros((K, 2, 2))
    A[:, 0, 0] = ds.alpha0
    A[:-1, 0, 1] = u[1:]
    A[:, 1, 1] = 1.0
    Qa = np.diag([Q, factor_walk**2 * ts])
    ra = kalman_filter_tv(
        A,
        Qa,
        np.array([[1.0, 0.0]]),
        np.array([[R]]),
        np.array([F_ds[0], 1.0]),
        np.diag([Q, 0.1**2]),
        y,
    )
    return ClampForceEstimates(
        kf=kf,
        kf_std=kf_std,
        kf_paper=kf_paper,
        kf_matched=matched,
        kf_paper_nis=nis,
        ml_fusion=F_ml,
        stiffness=F_ds,
        torque_balance=F_tb,
        adaptive=ra.x_filt[:, 0],
        adaptive_std=np.sqrt(ra.P_filt[:, 0, 0]),
        stiffness_factor=ra.x_filt[:, 1],
        stiffness_factor_std=np.sqrt(ra.P_filt[:, 1, 1]),
    )
