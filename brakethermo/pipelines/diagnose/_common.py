"""Constants, options and result types of the disc diagnosis."""

from __future__ import annotations

import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from brakethermo.diagnosis.verdict import (
    CandidateEvidence,
    VerdictRule,
)
from brakethermo.io.session import Session
from brakethermo.pipelines.tuning import TuningSource

MIN_SHRINK_PCT = 10.0  # % — lower bootstrap bound a verdict needs


CORRELATED = 0.8  # correlation of two effects' held-out corrections flagged as ambiguous
REFERENCE_WARNING = "reference model: "  # prefix of the warnings on the reference fit


PRIOR_WEIGHT_C = 5.0  # degC: one prior sigma costs like one residual of this size


BOOTSTRAP = 2000


MIN_STRAIGHT_S = 3.0  # s: shorter off-brake stretches join their neighbour's latent value


SPEED_BANDS_KMH = (0.0, 100.0, 200.0, 280.0)  # the last band ends at the session's top speed


TEMP_BANDS_C = (0.0, 250.0, 450.0, 650.0, 2000.0)


SETTLE_S = 5.0  # s after release counted as the "release" phase


RACE_SPOT = 3


RULE = VerdictRule(min_shrink_pct=MIN_SHRINK_PCT, correlated=CORRELATED, n_boot=BOOTSTRAP)


@dataclass(frozen=True)
class DiagnoseOptions:
    """Command-line choices of ``diagnose``."""

    effects: str | None = "all"
    holdout_laps: tuple[int, ...] | None = None
    h_law: str | Path | None = None
    disc: str | Path | None = None
    tuning: TuningSource = None
    aliases: str | Path | None = None
    ambient_c: float | None = None
    max_nfev: int = 25


@dataclass
class Candidate:
    """One effect fitted alone (or a combination): parameters and held-out scores."""

    name: str
    effects: tuple[str, ...]
    p: np.ndarray
    pred: np.ndarray  # (K, 4) held-out-ready prediction
    scored_spots: tuple[int, ...]
    fit_s: float
    scores: dict[str, Any] = field(default_factory=dict)


@dataclass
class DiagnoseResult:
    """Everything ``diagnose`` found; :attr:`summary` is ``diagnosis.json``."""

    session: Session
    summary: dict[str, Any]
    time: np.ndarray
    lap: np.ndarray
    y: np.ndarray
    reference_pred: np.ndarray
    best_pred: np.ndarray | None
    lap_distance: np.ndarray
    nis: np.ndarray
    timings: dict[str, float]
    reference_sse: np.ndarray | None = None  # (U, 4) held-out SSE per braking cycle
    evidence: list[CandidateEvidence] = field(default_factory=list)

    @property
    def stem(self) -> str:
        return self.session.path.stem


def filled(value: Any, fills: dict[str, str]) -> Any:
    """``value`` (a summary: dicts, lists, strings) with each placeholder of ``fills``
    replaced in every string — the suggested commands name where this run wrote."""
    if isinstance(value, str):
        for key, text in fills.items():
            value = value.replace(key, text)
        return value
    if isinstance(value, dict):
        return {k: filled(v, fills) for k, v in value.items()}
    if isinstance(value, list):
        return [filled(v, fills) for v in value]
    return value


def with_out(summary: Any, out: str | Path) -> Any:
    """``summary`` with the ``--out OUT`` placeholder of its suggested commands set to
    ``out`` (quoted for a shell), as :func:`filled` does."""
    return filled(summary, {"--out OUT": f"--out {shlex.quote(str(out))}"})
