"""Numeric helpers every layer may use (a base module, like ``errors`` and ``config``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def rmse(estimate: ArrayLike, reference: ArrayLike = 0.0, mask: ArrayLike | None = None
         ) -> float:
    """Root-mean-square of ``estimate - reference`` over the samples where both are finite
    (and ``mask``); NaN when none is.

    Parameters
    ----------
    estimate, reference : array_like — any unit; ``reference`` broadcasts (0: the RMS of
        ``estimate`` itself, e.g. of a residual).
    mask : array_like of bool, optional — samples to score.
    """
    d = np.asarray(estimate, float) - np.asarray(reference, float)
    ok = np.isfinite(d)
    if mask is not None:
        ok &= np.asarray(mask, bool)
    return float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("nan")


def noise_std(x: ArrayLike) -> float:
    """White-noise std of a smooth signal sampled densely: MAD of its first differences
    over sqrt(2) (finite neighbours only; NaN with fewer than three)."""
    d = np.diff(np.asarray(x, float))
    d = d[np.isfinite(d)]
    if d.size < 3:
        return float("nan")
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def true_runs(flag: ArrayLike) -> np.ndarray:
    """The runs of True in ``flag`` as half-open ``[start, stop)`` index rows, (n, 2) int."""
    f = np.asarray(flag, dtype=bool).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], f, [0]))))
    return edges.reshape(-1, 2)


def held_max(v: ArrayLike, width: int) -> float:
    """The largest value held over ``width`` samples: the maximum of a centred running
    median (edges held at the nearest sample), so a spike shorter than half of it drops
    out; the plain maximum of a series shorter than ``width``."""
    from scipy.ndimage import median_filter

    a = np.asarray(v, float)
    held = median_filter(a, size=width, mode="nearest") if a.size >= width else a
    return float(np.max(held))
