"""What ``mu-slip`` computed (:mod:`brakethermo.pipelines.mu_slip`), read by its pipeline,
its page (:mod:`brakethermo.report.mu_slip_page`) and the CLI alike."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from brakethermo.estimation.results import FilterResult
from brakethermo.io.session import Session
from brakethermo.models.mu_slip import FamilyFit, RelaxationChoice


@dataclass(frozen=True)
class MuSlipResult:
    """Everything ``mu-slip`` computed on one session."""

    session: Session
    time: np.ndarray
    slip: np.ndarray
    mu: np.ndarray
    sigma: float
    ekf: FilterResult
    lm_one_pass: tuple[np.ndarray, np.ndarray]
    lm_converged: tuple[np.ndarray, np.ndarray]
    families: list[FamilyFit]
    best: FamilyFit
    radius_m: float | None
    ramp_s: tuple[float, float]
    inflation: float
    points: bool = False
    ekf_noise_scale: float = 1.0  # factor on the EKF's covariance: its mean NIS if over-confident
    ekf_consistency: dict[str, Any] = field(default_factory=dict)  # of its innovations
    warnings: tuple[str, ...] = ()  # plausibility of the inputs and the result, in words
    relaxation: RelaxationChoice | None = None  # the slip's alignment with the force
