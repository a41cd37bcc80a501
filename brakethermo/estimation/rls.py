"""Recursive least squares with a forgetting factor (Mei et al. 2023, eq. 12a-d).

A general tool: fit ``y ≈ w' x`` sample by sample, the old samples discounted by
``lambda`` per step. The update is written so that rounding cannot destroy the
recursion on badly scaled regressors (polynomial terms s^2 ... s^8 span many decades):

* the regressor columns are scaled to unit RMS before the recursion and the weights
  scaled back afterwards (the solution is invariant to this change of variables,
  the conditioning of P is not);
* P is updated in Joseph form, ``P+ = [(I - k x') P (I - k x')' + lambda k k'] / lambda``,
  which is the eq. 12c update written as a sum of positive semi-definite terms (RLS is
  a Kalman filter with measurement-noise variance lambda), and kept symmetric;
* the gain denominator ``lambda + x' P x`` is at least lambda > 0.

P_0 = I / delta with a small ``delta`` (the paper's "delta I" is the inverse). With
``lam = 1`` the result is the ridge solution ``(X'X + delta I)^-1 X'y`` in the scaled
variables, i.e. the batch least-squares solution as ``delta -> 0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from brakethermo.errors import ConfigError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class RLSResult:
    """Output of :func:`rls_fit`.

    Attributes
    ----------
    w : ndarray (p,) — final weights, in the units of ``y`` per unit of each regressor.
    P : ndarray (p, p) — final recursion matrix in the original regressor units
        (symmetric); ``sigma^2 P`` approximates the covariance of ``w`` for lam = 1.
    w_history : ndarray (K, p) — weights after each sample (eq. 12d).
    error : ndarray (K,) — a-priori estimation error eps(k) (eq. 12a).
    lam : float — forgetting factor used.
    """

    w: Array
    P: Array
    w_history: Array
    error: Array
    lam: float


@numba.njit(cache=True)
def _rls_loop(X: Array, y: Array, w: Array, P: Array, lam: float) -> tuple[Array, Array]:
    K, p = X.shape
    W = np.empty((K, p))
    eps = np.empty(K)
    Px = np.empty(p)
    k = np.empty(p)
    A = np.empty((p, p))
    for t in range(K):
        x = X[t]
        e = y[t] - np.dot(w, x)  # eq. 12a
        for i in range(p):
            Px[i] = np.dot(P[i], x)
        den = lam + np.dot(x, Px)
        for i in range(p):
            k[i] = Px[i] / den  # eq. 12b
        # eq. 12c in Joseph form: A = (I - k x') P, P+ = (A (I - k x')' + lam k k') / lam
        for i in range(p):
            for j in range(p):
                A[i, j] = P[i, j] - k[i] * Px[j]
        for i in range(p):
            Ax = np.dot(A[i], x)
            for j in range(p):
                P[i, j] = (A[i, j] - Ax * k[j] + lam * k[i] * k[j]) / lam
        for i in range(p):
            for j in range(i + 1, p):
                s = 0.5 * (P[i, j] + P[j, i])
                P[i, j] = s
                P[j, i] = s
        for i in range(p):
            w[i] += k[i] * e  # eq. 12d (real data: eps* = eps)
            W[t, i] = w[i]  # by element: a row assignment compiles seconds of error paths
        eps[t] = e
    return W, eps


def rls_fit(
    X: Array,
    y: Array,
    *,
    lam: float = 1.0,
    delta: float = 1e-6,
    w0: Array | None = None,
) -> RLSResult:
    """Run RLS with forgetting factor over all samples.

    Parameters
    ----------
    X : ndarray (K, p) — regressor vectors x_RLS(k), one row per sample.
    y : ndarray (K,) — expected signal y_RLS(k).
    lam : float — forgetting factor lambda in (0, 1]; 1 keeps all samples equally.
    delta : float — P_0 = I / delta in the column-scaled variables (0 < delta << 1).
    w0 : ndarray (p,), optional — initial weights (default zero).

    Returns
    -------
    RLSResult
    """
    X = np.array(X, dtype=np.float64, order="C")
    y = np.array(y, dtype=np.float64).reshape(-1)
    if X.ndim != 2 or X.shape[0] != y.shape[0] or X.shape[0] < 1:
        raise ConfigError(f"RLS needs X (K, p) and y (K,), got {X.shape} and {y.shape}")
    if not (np.isfinite(X).all() and np.isfinite(y).all()):
        raise ConfigError("RLS regressors and targets must be finite")
    if not 0.0 < lam <= 1.0:
        raise ConfigError(f"forgetting factor must be in (0, 1], got {lam}")
    if not delta > 0.0:
        raise ConfigError(f"delta must be positive, got {delta}")
    p = X.shape[1]
    scale = np.sqrt(np.mean(X * X, axis=0))
    scale[scale == 0.0] = 1.0
    Xs = X / scale
    w = np.zeros(p) if w0 is None else np.array(w0, dtype=np.float64) * scale
    P = np.eye(p) / delta
    W, eps = _rls_loop(Xs, y, w, P, float(lam))
    Pw = P / np.outer(scale, scale)
    return RLSResult(
        w=W[-1] / scale, P=0.5 * (Pw + Pw.T), w_history=W / scale, error=eps, lam=float(lam)
    )


def even_powers(s: Array, powers: tuple[int, ...] = (2, 4, 6, 8)) -> Array:
    """Regressor rows [s^2, s^4, ...] of an even polynomial through the origin.

    Parameters
    ----------
    s : ndarray (K,) — abscissa (any unit; scale it to O(1) for good conditioning).
    powers : tuple of int — the exponents.

    Returns
    -------
    ndarray (K, len(powers))
    """
    s = np.asarray(s, dtype=np.float64).reshape(-1, 1)
    return s ** np.asarray(powers, dtype=np.float64)
