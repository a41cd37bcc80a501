"""Linear Kalman filter and exact RTS smoother, written out plainly (paper eq. 26-31).

A reference for the sigma-point machinery: it shares no code with it, so agreement
between the two on linear models is an independent check. :func:`kalman_filter_tv` is
the same recursion compiled, with a time-varying transition, for long rig logs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from brakethermo.errors import ConfigError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class LinearFilterResult:
    """Means and full covariances of a linear Kalman filter pass (K steps).

    Attributes
    ----------
    x_pred, x_filt : ndarray (K, n) — prior / posterior means.
    P_pred, P_filt : ndarray (K, n, n) — prior / posterior covariances.
    loglik : ndarray (K,) — log-likelihood of each step's used measurements.
    """

    x_pred: Array
    x_filt: Array
    P_pred: Array
    P_filt: Array
    loglik: Array


def _measurements(y: Array) -> Array:
    """y as float64 (K, m); a 1-D y is one measurement per step."""
    y = np.asarray(y, dtype=np.float64)
    return y[:, None] if y.ndim == 1 else y


def _outputs(K: int, n: int) -> tuple[Array, Array, Array, Array, Array]:
    """Empty x_pred, x_filt (K, n), P_pred, P_filt (K, n, n) and a zero loglik (K,)."""
    return (np.empty((K, n)), np.empty((K, n)), np.empty((K, n, n)), np.empty((K, n, n)),
            np.zeros(K))  # fmt: skip


def kalman_filter(
    A: Array,
    Q: Array,
    H: Array,
    R: Array,
    x0: Array,
    P0: Array,
    y: Array,
    b: Array | None = None,
) -> LinearFilterResult:
    """Linear KF for x_{k+1} = A x_k + b_k + q_k, y_k = H x_k + r_k.

    Parameters
    ----------
    A : ndarray (n, n) — transition matrix.
    Q : ndarray (n, n) — process-noise covariance.
    H : ndarray (m, n) — measurement matrix.
    R : ndarray (m, m) — measurement-noise covariance.
    x0, P0 : ndarray (n,), (n, n) — prior at step 0 (before y[0]).
    y : ndarray (K, m) — measurements, NaN = missing component.
    b : ndarray (K, n), optional — known input added to step k -> k+1.

    Returns
    -------
    LinearFilterResult
    """
    y = _measurements(y)
    K, n = y.shape[0], A.shape[0]
    if b is not None and b.shape != (K, n):
        raise ConfigError(f"input b must have shape ({K}, {n}), got {b.shape}")
    x_pred, x_filt, P_pred, P_filt, loglik = _outputs(K, n)
    x, P = np.array(x0, dtype=np.float64), np.array(P0, dtype=np.float64)
    for k in range(K):
        if k > 0:
            x = A @ x + (0.0 if b is None else b[k - 1])  # eq. 26
            P = A @ P @ A.T + Q  # eq. 27
        x_pred[k], P_pred[k] = x, P
        i = np.isfinite(y[k])
        if i.any():
            Hk, Rk = H[i], R[np.ix_(i, i)]
            S = Hk @ P @ Hk.T + Rk  # eq. 28
            Kg = np.linalg.solve(S, Hk @ P).T  # eq. 29 (S and P symmetric)
            nu = y[k, i] - Hk @ x
            x = x + Kg @ nu  # eq. 30
            P = P - Kg @ S @ Kg.T  # eq. 31
            P = 0.5 * (P + P.T)
            _, logdet = np.linalg.slogdet(2.0 * np.pi * S)
            loglik[k] = -0.5 * (nu @ np.linalg.solve(S, nu) + logdet)
        x_filt[k], P_filt[k] = x, P
    return LinearFilterResult(x_pred, x_filt, P_pred, P_filt, loglik)


def rts_smoother(A: Array, result: LinearFilterResult) -> tuple[Array, Array]:
    """Exact Rauch-Tung-Striebel smoother for the linear model of :func:`kalman_filter`.

    Returns
    -------
    x_smooth : ndarray (K, n)
    P_smooth : ndarray (K, n, n)
    """
    x_s, P_s = result.x_filt.copy(), result.P_filt.copy()
    for k in range(x_s.shape[0] - 2, -1, -1):
        Pp = result.P_pred[k + 1]
        G = np.linalg.solve(Pp, A @ result.P_filt[k]).T  # P_k A' (P_{k+1}^-)^-1
        x_s[k] = result.x_filt[k] + G @ (x_s[k + 1] - result.x_pred[k + 1])
        P_s[k] = result.P_filt[k] + G @ (P_s[k + 1] - Pp) @ G.T
        P_s[k] = 0.5 * (P_s[k] + P_s[k].T)
    return x_s, P_s


@njit(cache=True, nogil=True)
def _kf_tv_kernel(A, Q, H, R, x0, P0, y, b, x_pred, x_filt, P_pred, P_filt, loglik):
    K = x_pred.shape[0]
    x, P = x0.copy(), P0.copy()
    for k in range(K):
        if k > 0:
            Ak = A[k - 1] if A.shape[0] > 1 else A[0]
            x = Ak @ x + b[k - 1]  # eq. 26
            P = Ak @ P @ Ak.T + Q  # eq. 27
        x_pred[k], P_pred[k] = x, P
        if np.isfinite(y[k]).all():
            S = H @ P @ H.T + R  # eq. 28
            Kg = np.linalg.solve(S, H @ P).T  # eq. 29
            nu = y[k] - H @ x
            x = x + Kg @ nu  # eq. 30
            P = P - Kg @ S @ Kg.T  # eq. 31
            P = 0.5 * (P + P.T)
            loglik[k] = -0.5 * (
                nu @ np.linalg.solve(S, nu) + np.log(np.linalg.det(2.0 * np.pi * S))
            )
        x_filt[k], P_filt[k] = x, P


def kalman_filter_tv(
    A: Array,
    Q: Array,
    H: Array,
    R: Array,
    x0: Array,
    P0: Array,
    y: Array,
    b: Array | None = None,
) -> LinearFilterResult:
    """Compiled linear KF with an optional time-varying transition, for long small-state runs.

    The equations of :func:`kalman_filter` (eq. 26-31) in one numba loop: a scalar or
    two-state filter over a 60 s kHz log costs milliseconds instead of seconds. A step
    whose measurement has any NaN component is predict-only.

    Parameters
    ----------
    A : ndarray (n, n) or (K, n, n) — transition; ``A[k]`` maps step k to k + 1.
    Q, H, R, x0, P0, y, b
        As :func:`kalman_filter`.

    Returns
    -------
    LinearFilterResult
    """
    y = _measurements(y)
    K = y.shape[0]
    A = np.asarray(A, dtype=np.float64)
    n = A.shape[-1]
    if A.ndim == 2:
        A = A[None]
    if A.ndim != 3 or A.shape[0] not in (1, K) or A.shape[1:] != (n, n):
        raise ConfigError(f"A must have shape ({n}, {n}) or ({K}, {n}, {n}), got {A.shape}")
    if b is None:
        b = np.zeros((K, n))
    elif b.shape != (K, n):
        raise ConfigError(f"input b must have shape ({K}, {n}), got {b.shape}")
    x_pred, x_filt, P_pred, P_filt, loglik = _outputs(K, n)
    f64 = np.float64
    _kf_tv_kernel(
        np.ascontiguousarray(A), np.asarray(Q, f64), np.asarray(H, f64), np.asarray(R, f64),
        np.asarray(x0, f64), np.asarray(P0, f64), y, np.asarray(b, f64),
        x_pred, x_filt, P_pred, P_filt, loglik,
    )
    return LinearFilterResult(x_pred, x_filt, P_pred, P_filt, loglik)
