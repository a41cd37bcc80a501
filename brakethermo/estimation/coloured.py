"""Two sources of one signal, one with a slowly varying error: that error as a state.

A model-based source whose error is not white (a stiffness curve that misses hysteresis
and relaxation: its error holds for tens of milliseconds) and a noisier source whose
error is closer to white (a torque balance) are fused by the paper's filters as if both
errors were white; with a static model the Kalman filter is then the ML fusion. Here the
first source's error b is a first-order Gauss–Markov process (coloured noise carried as a
state, Bryson & Henrikson 1968),

    b(k) = φ b(k−1) + w,   m(k) = s1(k) − s2(k) = b(k) + v,

observed through the difference of the two sources, and the estimate is s1 − b̂. The
filter is the steady-state scalar Kalman filter (gain g) and, since the log is processed
after the run, its steady-state Rauch–Tung–Striebel smoother. The pair (φ, g) spans every
such filter (for a measurement variance r, q = g r/(1−g) − φ² g r > 0), and φ = 0 with
g = q/(q+r) is the ML fusion (one gain for the whole log), so a choice of (φ, g) on
held-out data is no worse there than it, up to the grid of gains tried.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

Array = NDArray[np.float64]


def error_filter(m: Array, phi: float, g: float) -> tuple[Array, Array]:
    """Filtered error and the innovations of the steady-state filter.

    Parameters
    ----------
    m : ndarray (K,) — the difference of the two sources, in the sources' unit; a NaN
        (a derivative window's edge) counts as a measured 0, the error's prior mean.
    phi : float — the error's one-step correlation, e^(−ts/τ), –.
    g : float — the steady-state Kalman gain, 0 < g < 1, –.

    Returns
    -------
    b_filt : ndarray (K,) — b̂(k|k) = (1 − g) φ b̂(k−1|k−1) + g m(k).
    nu : ndarray (K,) — innovations m(k) − φ b̂(k−1|k−1).
    """
    m = np.nan_to_num(np.asarray(m, float))
    b_filt = lfilter([g], [1.0, -(1.0 - g) * phi], m)
    b_pred = np.concatenate([[0.0], phi * b_filt[:-1]])
    return b_filt, m - b_pred


def error_smoother(m: Array, phi: float, g: float) -> Array:
    """The steady-state RTS smoother's error estimate b̂(k|K).

    With P(k|k) = (1 − g) P(k|k−1) in steady state the smoother gain is
    C = P(k|k) φ / P(k+1|k) = (1 − g) φ, and b̂(k|K) = b̂(k|k) + C (b̂(k+1|K) − φ b̂(k|k)).
    Parameters as :func:`error_filter`.
    """
    b_filt, _ = error_filter(m, phi, g)
    C = (1.0 - g) * phi
    # started so that b̂(K−1|K) = b̂(K−1|K−1)
    b_rev, _ = lfilter([1.0 - C * phi], [1.0, -C], b_filt[::-1], zi=[C * phi * b_filt[-1]])
    return b_rev[::-1]


def smoothed_variance(phi: float, g: float, r: float) -> float:
    """Steady-state variance of b̂(k|K): P_s = (P⁺ − C² P⁻) / (1 − C²).

    Parameters
    ----------
    phi, g : as :func:`error_filter`.
    r : float — variance of the second source's error (m's white part), unit².
    """
    P_pred = g * r / (1.0 - g)
    P_filt = g * r
    C = (1.0 - g) * phi
    return (P_filt - C**2 * P_pred) / (1.0 - C**2)
