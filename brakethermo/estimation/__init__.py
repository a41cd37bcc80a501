"""Model-agnostic estimation engine: sigma-point filters and smoothers, EKF, KF, RLS."""

from brakethermo.estimation.augment import augment_random_walk
from brakethermo.estimation.covariance import CovarianceGuard, symmetrise
from brakethermo.estimation.ekf import ExtendedKalmanFilter, batched_jacobian
from brakethermo.estimation.kf import LinearFilterResult, kalman_filter, rts_smoother
from brakethermo.estimation.results import FilterResult, SmootherResult
from brakethermo.estimation.sigma_points import MerweWeights, merwe_weights, sigma_points
from brakethermo.estimation.ukf import UnscentedKalmanFilter
from brakethermo.estimation.urts import urts_smooth

__all__ = [
    "CovarianceGuard",
    "ExtendedKalmanFilter",
    "FilterResult",
    "LinearFilterResult",
    "MerweWeights",
    "SmootherResult",
    "UnscentedKalmanFilter",
    "augment_random_walk",
    "batched_jacobian",
    "kalman_filter",
    "merwe_weights",
    "rts_smoother",
    "sigma_points",
    "symmetrise",
    "urts_smooth",
]
