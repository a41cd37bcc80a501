"""filterpy's UKF on our batched model: the reference the filter benchmarks time and compare.

Imported by the ``bench_*.py`` scripts beside it (run as ``python benchmarks/bench_*.py``,
which puts this folder on the import path).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints
from filterpy.kalman import UnscentedKalmanFilter as FilterpyUKF


def run_filterpy_ukf(
    f: Callable[[np.ndarray, int], np.ndarray],
    H: np.ndarray,
    Q: np.ndarray,
    R: np.ndarray,
    x0: np.ndarray,
    P0: np.ndarray,
    y: np.ndarray,
    steps: int,
    alpha: float,
    beta: float,
    kappa: float,
) -> tuple[float, np.ndarray]:
    """filterpy's ``UnscentedKalmanFilter`` over the first ``steps`` rows of ``y``.

    The same model as ours: ``f(X (B, n), k) -> (B, n)`` called on one point at a time
    (filterpy's way), measurement ``H x``, the same scaled sigma points.

    Returns
    -------
    (seconds, x_filt) — wall time of the filtering loop alone, s, and the filtered means
    (steps, n).
    """
    n = x0.shape[0]
    pts = MerweScaledSigmaPoints(n, alpha=alpha, beta=beta, kappa=kappa)
    # fx ignores dt: the model's step is fixed by the model itself
    fp = FilterpyUKF(dim_x=n, dim_z=H.shape[0], dt=1.0, hx=lambda x: H @ x,
                     fx=lambda x, dt, k: f(x[None], k)[0], points=pts)  # fmt: skip
    fp.x, fp.P, fp.Q, fp.R = x0.copy(), P0.copy(), Q, R
    fp.sigmas_f = pts.sigma_points(fp.x, fp.P)
    xs = np.empty((steps, n))
    t = time.perf_counter()
    for k in range(steps):
        if k > 0:
            fp.predict(k=k - 1)
        fp.update(y[k])
        xs[k] = fp.x
    return time.perf_counter() - t, xs
