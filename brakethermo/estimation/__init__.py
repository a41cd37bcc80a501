"""Model-agnostic estimation engine: sigma-point filters and smoothers, EKF, KF, RLS.

Usage (a batched model ``f(X (B, n), k) -> (B, n)`` advancing all rows from step k to
k + 1, a linear measurement ``H`` and measurements ``y`` (K, m) with NaN for gaps)::

    ukf = UnscentedKalmanFilter(f, Q, R, H=H)
    res = ukf.run(x0, P0, y, store="smoother", readout=H_spots)   # FilterResult
    sm = urts_smooth(res, readout=H_spots)                        # SmootherResult

The smoother reuses the gains stored by the forward pass and never calls the model.
Random-walk parameters are extra state components (:func:`augment_random_walk`).
"""

from brakethermo.estimation.augment import augment_random_walk
from brakethermo.estimation.covariance import CovarianceGuard, symmetrise
from brakethermo.estimation.ekf import ExtendedKalmanFilter, batched_jacobian
from brakethermo.estimation.kf import (
    LinearFilterResult,
    kalman_filter,
    kalman_filter_tv,
    rts_smoother,
)
from brakethermo.estimation.results import FilterResult, SmootherResult
from brakethermo.estimation.rls import RLSResult, even_powers, rls_fit
from brakethermo.estimation.sigma_points import MerweWeights, merwe_weights, sigma_points
from brakethermo.estimation.ukf import UnscentedKalmanFilter
from brakethermo.estimation.urts import urts_smooth

__all__ = [
    "CovarianceGuard",
    "ExtendedKalmanFilter",
    "FilterResult",
    "LinearFilterResult",
    "MerweWeights",
    "RLSResult",
    "SmootherResult",
    "UnscentedKalmanFilter",
    "augment_random_walk",
    "batched_jacobian",
    "even_powers",
    "kalman_filter",
    "kalman_filter_tv",
    "merwe_weights",
    "rls_fit",
    "rts_smoother",
    "sigma_points",
    "symmetrise",
    "urts_smooth",
]
