"""Signal helpers the rig models share."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
SPEED_WINDOW_S = 0.02  # s, moving average of a rig input's rate (encoder quantisation)


def smoothed_rate(x: Array, dt: float, window_s: float = 0.02) -> Array:
    """Rate of change of ``x`` per second after a ``window_s`` moving average (an
    encoder's quantisation steps would otherwise read as spikes of speed).

    Parameters
    ----------
    x : ndarray (K,) — the signal, any unit.
    dt : float — s, sample step.
    window_s : float — s, moving-average length (at least one sample).
    """
    width = max(1, round(window_s / dt))
    smooth = np.convolve(np.pad(x, (width // 2, width - 1 - width // 2), mode="edge"),
                         np.ones(width) / width, mode="valid")
    return np.gradient(smooth, dt)
