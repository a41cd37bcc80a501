"""What ``clamp-force`` computed (:mod:`brakethermo.pipelines.clamp_force`), read by its
pipeline, its page (:mod:`brakethermo.report.clamp_force_page`) and the CLI alike."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from brakethermo.io.session import Session
from brakethermo.models.clamp_force import (
    SENSOR_LAGS_S,
    ClampForceEstimates,
    ClampForceModels,
    FusionCheck,
)
from brakethermo.rigs.emb import sensor_delagged

ESTIMATORS = ("kf", "kf_paper", "ml_fusion", "stiffness", "torque_balance", "kf_adaptive")
PEAK_HOLD_S = 0.005  # s: a peak force is one held this long (not a current-step spike)


@dataclass(frozen=True)
class EmbData:
    """The arrays of one caliper session: angle rad, current A, sensor N (or None), step s."""

    session: Session
    theta: np.ndarray
    current: np.ndarray
    force: np.ndarray | None
    ts: float


LAG_MIN_SHRINK_PCT = 1.0  # % — lower bootstrap bound of the current RMSE shrink


@dataclass(frozen=True)
class SensorLag:
    """The clamp-force sensor's lag as one session shows it
    (:func:`brakethermo.pipelines.clamp_force.choose_sensor_lag`).

    Attributes
    ----------
    lag_s : float — s, the lag taken out (0: the paper's ideal sensor kept).
    best_s : float — s, the candidate with the smallest held-out current error.
    current_rmse_a : dict — held-out motor-current RMSE (A) per candidate lag (s).
    shrink_pct : tuple of float — the best candidate's current RMSE shrink against no
        lag, %, and its 95 % bootstrap interval over the blocks.
    eq7 : (int, float) — eq. 7's derivative window and friction sign band chosen on the
        sensor with ``lag_s`` taken out.
    """

    lag_s: float
    best_s: float
    current_rmse_a: dict[float, float]
    shrink_pct: tuple[float, float, float]
    eq7: tuple[int, float]

    @property
    def at_edge(self) -> bool:
        """The largest candidate won: the sensor may lag more than it says."""
        return self.best_s == SENSOR_LAGS_S[-1]

    def as_dict(self) -> dict[str, Any]:
        shrink, lo, hi = self.shrink_pct
        return {
            "lag_s": self.lag_s, "best_candidate_s": self.best_s,
            "heldout_current_rmse_a_by_lag_ms": {f"{k * 1e3:g}": v
                                                 for k, v in self.current_rmse_a.items()},
            "shrink_pct": shrink, "shrink_ci95_pct": [lo, hi], "at_grid_edge": self.at_edge,
            "what": "the clamp-force sensor's first-order lag: of the candidates"
                    f" {SENSOR_LAGS_S[0] * 1e3:g}–{SENSOR_LAGS_S[-1] * 1e3:g} ms, the one"
                    " whose de-lagged sensor (F + τ dF/dt) lets the torque balance (eq. 7,"
                    " plus a viscous term so that no speed-proportional friction passes"
                    " for a lag) predict the motor current best on held-out 2 s blocks,"
                    " taken out when that shrinks the current RMSE by more than"
                    f" {LAG_MIN_SHRINK_PCT:g} % at the lower end of a 95 % bootstrap"
                    " interval (else 0)",
        }


@dataclass(frozen=True)
class ClampForceResult:
    """Everything ``clamp-force`` computed."""

    data: EmbData
    train: EmbData
    models: ClampForceModels
    est: ClampForceEstimates
    retrain: EmbData | None
    models_retrained: ClampForceModels | None
    est_retrained: ClampForceEstimates | None
    check: FusionCheck | None = None  # the fusion against its inputs, held out in training
    check_retrained: FusionCheck | None = None
    train_lag: SensorLag | None = None  # the training sensor's lag
    scored_lag: SensorLag | None = None  # this session's sensor's own, when it has one

    @property
    def reported(self) -> ClampForceEstimates:
        """The session's estimate: the re-trained models' where pads were re-trained (the
        user's statement that the training session's pads are gone), else the training's."""
        return self.est if self.est_retrained is None else self.est_retrained

    @property
    def reported_check(self) -> FusionCheck | None:
        return self.check if self.est_retrained is None else self.check_retrained


def estimator_series(est: ClampForceEstimates) -> dict[str, np.ndarray]:
    """Each estimator's clamp force by output column name, N, constrained to >= 0.

    Pads only push: where an estimator's mean sits below zero (after a release, the
    torque balance's friction, the filter's Gaussian) the reported force is the most
    probable value of that Gaussian truncated at zero — zero; the band keeps its spread
    (as the booster's gauge pressure).
    """
    return {name: np.maximum(v, 0.0) for name, v in (
        ("kf", est.kf),
        ("kf_paper", est.kf_paper),
        ("ml_fusion", est.ml_fusion),
        ("stiffness", est.stiffness),
        ("torque_balance", est.torque_balance),
        ("kf_adaptive", est.adaptive),
    )}


def scored_force(res: ClampForceResult) -> np.ndarray | None:
    """The estimated session's sensor (N) with its own lag taken out
    (:func:`~brakethermo.pipelines.clamp_force.choose_sensor_lag` on this session), what
    ``rmse_kn`` scores against (None without the sensor).

    A session too short to choose its sensor's lag on (a 2 s one) is scored against its
    sensor as logged: it was said to have no sensor, and nothing was scored."""
    force, lag = res.data.force, res.scored_lag
    if force is None:
        return None
    return force if lag is None else sensor_delagged(force, lag.lag_s, res.data.ts)


KF_NAMES = {"fixed": "the paper's KF (eq. 9-13)",
            "adaptive": "adaptive KF (stiffness factor)",
            "coloured": "KF smoother, coloured stiffness error"}
SOURCE_NAMES = {"stiffness": "dynamic-stiffness model (eq. 6)",
                "torque_balance": "torque-balance model (eq. 7)",
                "ml_fusion": "ML fusion (eq. 8)"}
