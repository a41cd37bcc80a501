"""Scaled (van der Merwe) sigma points and their weights (paper eq. 32-34)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from brakethermo.errors import ConfigError


@dataclass(frozen=True)
class MerweWeights:
    """Weights of the scaled unscented transform for an ``n``-dimensional state.

    Attributes
    ----------
    n : int — state dimension.
    alpha, beta, kappa : float — spread, prior-knowledge and secondary scaling parameters.
    lam : float — lambda = alpha^2 (n + kappa) - n.
    c : float — sqrt(n + lambda), the scale of the Cholesky columns (eq. 33-34).
    Wm, Wc : ndarray (2n+1,) — mean and covariance weights (eq. 36-37).
    """

    n: int
    alpha: float
    beta: float
    kappa: float
    lam: float
    c: float
    Wm: NDArray[np.float64]
    Wc: NDArray[np.float64]


def merwe_weights(
    n: int, alpha: float = 0.1, beta: float = 2.0, kappa: float = 0.0
) -> MerweWeights:
    """Build the Merwe scaled sigma-point weights (same convention as filterpy).

    Parameters
    ----------
    n : int — state dimension.
    alpha : float — spread of the points around the mean, 0 < alpha <= 1.
    beta : float — 2 is optimal for Gaussian priors.
    kappa : float — secondary scaling, usually 0 or 3 - n.

    Returns
    -------
    MerweWeights
    """
    if n < 1:
        raise ConfigError(f"sigma points need a state dimension >= 1, got {n}")
    if not alpha > 0.0:
        raise ConfigError(f"unscented alpha must be > 0, got {alpha}")
    lam = alpha**2 * (n + kappa) - n
    if not n + lam > 0.0:
        raise ConfigError(f"n + lambda must be > 0 (n={n}, alpha={alpha}, kappa={kappa})")
    Wm = np.full(2 * n + 1, 0.5 / (n + lam))
    Wc = Wm.copy()
    Wm[0] = lam / (n + lam)
    Wc[0] = lam / (n + lam) + (1.0 - alpha**2 + beta)
    for w in (Wm, Wc):
        w.setflags(write=False)
    return MerweWeights(n, alpha, beta, kappa, lam, float(np.sqrt(n + lam)), Wm, Wc)


def sigma_points(
    m: NDArray[np.float64], L: NDArray[np.float64], c: float, out: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """Sigma points chi = [m, m + c L_i, m - c L_i] as rows (eq. 32-34).

    Parameters
    ----------
    m : ndarray (n,) — mean.
    L : ndarray (n, n) — lower Cholesky factor of the covariance, P = L L'.
    c : float — sqrt(n + lambda).
    out : ndarray (2n+1, n), optional — preallocated buffer to fill.

    Returns
    -------
    ndarray (2n+1, n)
    """
    n = m.shape[0]
    X = np.empty((2 * n + 1, n)) if out is None else out
    X[0] = m
    np.multiply(L.T, c, out=X[1 : n + 1])
    np.negative(X[1 : n + 1], out=X[n + 1 :])
    X[1:] += m
    return X
