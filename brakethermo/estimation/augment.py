"""Parameters as random-walk states (paper eq. 48): x' = [x, theta], theta_{k+1} = theta_k + w."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from brakethermo.errors import ConfigError

Array = NDArray[np.float64]


def augment_random_walk(
    f_x: Callable[[Array, Array, int], Array],
    n_x: int,
    Q_x: Array,
    q_theta: Array,
) -> tuple[Callable[[Array, int], Array], Array]:
    """Batched transition and process noise of the state augmented with parameters.

    Parameters
    ----------
    f_x : callable ``f_x(X (B, n_x), Theta (B, p), k) -> (B, n_x)`` — the model, given
        the parameter value of each sigma point.
    n_x : int — number of physical states.
    Q_x : ndarray (n_x, n_x) — process noise of the physical states.
    q_theta : ndarray (p,) — random-walk variance of each parameter per step,
        in squared parameter units.

    Returns
    -------
    f : callable ``f(X (B, n_x + p), k) -> (B, n_x + p)`` — carries the parameters unchanged.
    Q : ndarray (n_x + p, n_x + p) — block-diagonal process noise.
    """
    q_theta = np.atleast_1d(np.asarray(q_theta, dtype=np.float64))
    Q_x = np.asarray(Q_x, dtype=np.float64)
    if Q_x.shape != (n_x, n_x):
        raise ConfigError(f"Q_x must have shape ({n_x}, {n_x}), got {Q_x.shape}")
    if np.any(q_theta < 0.0):
        raise ConfigError("random-walk variances must be >= 0")
    p = q_theta.shape[0]
    Q = np.zeros((n_x + p, n_x + p))
    Q[:n_x, :n_x] = Q_x
    Q[n_x:, n_x:] = np.diag(q_theta)

    def f(X: Array, k: int) -> Array:
        out = np.empty_like(X)
        out[:, :n_x] = f_x(X[:, :n_x], X[:, n_x:], k)
        out[:, n_x:] = X[:, n_x:]
        return out

    return f, Q
