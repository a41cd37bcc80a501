"""The E-Booster observer's results: what the pipeline computes and the page reads."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from brakethermo.estimation.results import FilterResult
from brakethermo.io.session import Session
from brakethermo.models.ebooster import BoosterFit
from brakethermo.rigs.booster_datasheet import BoosterSpec

Array = NDArray[np.float64]
PRESSURES = {
    "p_m": "master_cylinder_pressure",
    "p_f": "front_circuit_pressure",
    "p_r": "rear_circuit_pressure",
}
OBSERVERS = ("ukf", "ekf")


@dataclass(frozen=True)
class ObserverTrack:
    """One observer's output over the session (model units).

    Attributes
    ----------
    x, std : ndarray (K, 5) — state and 1 sigma (smoothed when ``smoothed``).
    residual : ndarray (K,) — mm, measured minus one-step-predicted delta (innovation).
    filt : FilterResult — the forward pass.
    smoothed : bool
    seconds : float — wall time of filter + smoother.
    consistency : dict — the forward pass's NIS against its χ² band.
    noise_scale : float — factor on the filter's variance in ``std`` (its mean NIS where
        over-confident, else 1).
    """

    x: Array
    std: Array
    residual: Array
    filt: FilterResult
    smoothed: bool
    seconds: float
    consistency: dict[str, Any] = field(default_factory=dict)
    noise_scale: float = 1.0


@dataclass(frozen=True)
class EboosterResult:
    """Everything the writers and the report need."""

    session: Session
    spec: BoosterSpec
    fit: BoosterFit
    time: Array
    s2: Array
    delta: Array
    validation: dict[str, Array]
    tracks: dict[str, ObserverTrack]
    summary: dict[str, Any]


def static_pressure(result: EboosterResult) -> Array:
    """MPa, the p-V curve at the session's s2 (what the model predicts without delta)."""
    return result.fit.pressure(result.s2)
