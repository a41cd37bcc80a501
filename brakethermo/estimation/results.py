"""Containers for filter and smoother outputs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ForwardTrace:
    """The per-step record of a forward pass over K steps (m measured), small whatever
    the state size: a windowed run keeps it without the (K, n) state stacks
    (:class:`FilterResult` is this record plus them; build a ``ForwardTrace`` itself
    where only the record is to be kept).

    Attributes
    ----------
    innovation : ndarray (K, m) — y - predicted measurement, NaN where not used.
    innovation_var : ndarray (K, m) — diagonal of S, NaN where not used.
    nis : ndarray (K,) — normalised innovation squared nu' S^-1 nu, NaN on
        predict-only steps.
    loglik : ndarray (K,) — log N(y_k; mu_k, S_k), 0 on predict-only steps.
    n_obs : ndarray (K,) int — measurement components used at each step.
    rejected : ndarray (K,) bool — steps whose measurement failed the innovation gate.
    readout, readout_var : ndarray (K, p) or None — M x_filt and diag(M P_filt M') for
        the caller's readout matrix M.
    n_repairs : int — covariance repairs (non-SPD matrices clipped).
    repair_steps : tuple[int, ...] — steps at which repairs happened.
    """

    innovation: Array
    innovation_var: Array
    nis: Array
    loglik: Array
    n_obs: NDArray[np.int64]
    rejected: NDArray[np.bool_]
    readout: Array | None
    readout_var: Array | None
    n_repairs: int
    repair_steps: tuple[int, ...]

    @property
    def log_likelihood(self) -> float:
        """Total log-likelihood of the used measurements."""
        return float(np.sum(self.loglik))


@dataclass(frozen=True)
class FilterResult(ForwardTrace):
    """Output of a forward filter pass over K steps (state dimension n): the per-step
    record of :class:`ForwardTrace` and the state and covariance stacks.

    Step k's prior (x_pred, P_pred) is the prediction before y[k]; step 0's prior is
    (x0, P0). The posterior (x_filt, P_filt) includes y[k].

    Attributes
    ----------
    x_pred, x_filt : ndarray (K, n) — prior and posterior means.
    var_pred, var_filt : ndarray (K, n) — diagonals of P_pred and P_filt.
    P_pred, P_filt : ndarray (K, n, n) or None — full covariances (``store="full"``).
    cross : ndarray (K-1, n, n) or None — C_k = cov(x_k, x_{k+1} | y_0..k), the
        cross-covariance of the prediction (``store="full"``).
    G : ndarray (K-1, n, n) or None — RTS gains G_k = C_k P_pred[k+1]^-1
        (``store`` "full" or "smoother").
    Sigma : ndarray (K-1, n, n) or None — P_filt[k] - G_k P_pred[k+1] G_k'
        (``store`` "full" or "smoother"); with ``G`` it is all the smoother needs.
    P_last : ndarray (n, n) — posterior covariance of the last step (the smoother's start).
    store : str — what was stored: "full", "smoother" or "diag".
    """

    x_pred: Array
    x_filt: Array
    var_pred: Array
    var_filt: Array
    P_pred: Array | None
    P_filt: Array | None
    cross: Array | None
    G: Array | None
    Sigma: Array | None
    P_last: Array
    store: str

    @property
    def nbytes(self) -> int:
        """Memory held by the arrays, bytes."""
        return sum(v.nbytes for v in self.__dict__.values() if isinstance(v, np.ndarray))


@dataclass(frozen=True)
class SmootherResult:
    """Output of a Rauch-Tung-Striebel backward pass.

    Attributes
    ----------
    x_smooth : ndarray (K, n) — smoothed means.
    var_smooth : ndarray (K, n) — diagonal of the smoothed covariances.
    P_smooth : ndarray (K, n, n) or None — full smoothed covariances (``store="full"``).
    readout, readout_var : ndarray (K, p) or None — M x_smooth and diag(M P_smooth M').
    P_first : ndarray (n, n) or None — smoothed covariance of step 0 (where a window
        hands over to the one before it).
    """

    x_smooth: Array
    var_smooth: Array
    P_smooth: Array | None
    readout: Array | None
    readout_var: Array | None
    P_first: Array | None = None


@dataclass(frozen=True)
class WindowedSmootherResult:
    """Forward pass and unscented RTS smoother run window by window.

    Attributes
    ----------
    forward : ForwardTrace — the filter's per-step record (readouts of the filtered state).
    smoothed : SmootherResult — the smoothed means, variances and readouts.
    windows : tuple of (start, stop) — the step ranges the run was cut into.
    peak_store_bytes : int — largest memory held by gains at one time, bytes.
    forward_s, backward_s : float — s, wall time of the first forward pass and of the
        backward pass with the windows' re-runs.
    """

    forward: ForwardTrace
    smoothed: SmootherResult
    windows: tuple[tuple[int, int], ...]
    peak_store_bytes: int
    forward_s: float
    backward_s: float
