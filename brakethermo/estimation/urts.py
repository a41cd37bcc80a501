"""Rauch-Tung-Striebel backward pass for sigma-point and extended Kalman filters.

The forward pass stores, per step, the gain G_k = C_k (P_{k+1}^-)^-1 and
Sigma_k = P_k - G_k P_{k+1}^- G_k', with C_k the cross-covariance of the prediction
(from the UKF's propagated sigma set, Särkkä's unscented RTS smoother). The backward
recursion

    m_k^s = m_k + G_k (m_{k+1}^s - m_{k+1}^-)
    P_k^s = Sigma_k + G_k P_{k+1}^s G_k'

therefore needs no model re-evaluation and no matrix inversion.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from brakethermo.errors import ConfigError
from brakethermo.estimation._forward import readout_matrix
from brakethermo.estimation.covariance import symmetrise
from brakethermo.estimation.results import FilterResult, SmootherResult
from brakethermo.estimation.ukf import BACKENDS, HAVE_NUMBA, NUMBA_MAX_N, Backend

Array = NDArray[np.float64]


def urts_smooth(
    result: FilterResult,
    *,
    store: Literal["full", "diag"] = "diag",
    readout: Array | None = None,
    backend: Backend = "auto",
) -> SmootherResult:
    """Smooth a forward pass run with ``store="full"`` or ``store="smoother"``.

    Parameters
    ----------
    result : FilterResult — output of UnscentedKalmanFilter.run or ExtendedKalmanFilter.run.
    store : {"full", "diag"} — keep all smoothed covariances (K, n, n) or their diagonals.
    readout : ndarray (p, n), optional — matrix M whose M x^s and diag(M P^s M') are
        recorded (e.g. interpolation to sensor radii).
    backend : {"auto", "numba", "numpy"} — compiled loop or numpy; "auto" as the UKF.

    Returns
    -------
    SmootherResult
    """
    if result.G is None or result.Sigma is None:
        raise ConfigError(
            "the smoother needs the forward pass run with store='smoother' or 'full', "
            f"got store={result.store!r}"
        )
    if store not in ("full", "diag"):
        raise ConfigError(f"smoother store must be 'full' or 'diag', got {store!r}")
    K, n = result.x_filt.shape
    M = None if readout is None else readout_matrix(readout, n)
    x_s = np.empty((K, n))
    var_s = np.empty((K, n))
    P_all = np.empty((K, n, n)) if store == "full" else None
    ro = None if M is None else np.empty((K, M.shape[0]))
    ro_var = None if M is None else np.empty((K, M.shape[0]))

    x_filt, x_pred, G_all, Sigma_all = result.x_filt, result.x_pred, result.G, result.Sigma
    if backend not in BACKENDS:
        raise ConfigError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "numba" and not HAVE_NUMBA:
        raise ConfigError("backend='numba' asked for but numba is not installed")
    if backend == "numba" or (backend == "auto" and HAVE_NUMBA and n <= NUMBA_MAX_N):
        from brakethermo.estimation._kernels import rts_backward

        rts_backward(
            x_filt, x_pred, G_all, Sigma_all, result.P_last, x_s, var_s,
            np.empty((0, n, n)) if P_all is None else P_all, P_all is not None,
            np.zeros((0, n)) if M is None else M, np.empty((K, 0)) if ro is None else ro,
            np.empty((K, 0)) if ro_var is None else ro_var,
        )  # fmt: skip
        return SmootherResult(
            x_smooth=x_s, var_smooth=var_s, P_smooth=P_all, readout=ro, readout_var=ro_var
        )
    xs = x_filt[K - 1].copy()
    Ps = result.P_last.copy()
    for k in range(K - 1, -1, -1):
        if k < K - 1:
            G = G_all[k].astype(np.float64, copy=False)
            xs = x_filt[k] + G @ (xs - x_pred[k + 1])
            Ps = symmetrise(Sigma_all[k] + G @ Ps @ G.T)
        x_s[k] = xs
        var_s[k] = np.diagonal(Ps)
        if P_all is not None:
            P_all[k] = Ps
        if M is not None:
            ro[k] = M @ xs
            ro_var[k] = np.einsum("ij,jk,ik->i", M, Ps, M)
    return SmootherResult(
        x_smooth=x_s, var_smooth=var_s, P_smooth=P_all, readout=ro, readout_var=ro_var
    )
