"""The roller rig's results: what the pipeline computes and the page reads."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from brakethermo.io.session import Session
from brakethermo.rigs.roller_rig import RollerRigSpec


@dataclass(frozen=True)
class GuessRun:
    """One starting guess: tracks in mm on the session grid and its figures."""

    r0_mm: float
    radius_mm: np.ndarray  # the output track (smoothed when the smoother is on)
    radius_std_mm: np.ndarray
    filter_mm: np.ndarray  # the forward filter's track (the paper's)
    filter_std_mm: np.ndarray
    states: np.ndarray  # (K, 3) output means
    convergence_time_s: float | None
    restart: str | None = None  # why the guess was re-started from the speed ratio
    model_error_mm_per_knm: float = 0.0  # the creep law's error in the bands, mm per kN m
    consistency: dict[str, Any] | None = None  # the filter's NIS against its chi-square band
    noise_scale: float = 1.0  # factor on the filter's variance: its mean NIS if over-confident
    ratio_offset_mm: float = 0.0  # mean free-rolling radius minus the speed-ratio radius
    ratio_error_mm: float = 0.0  # what that departure adds to the bands (1 sigma), mm


@dataclass(frozen=True)
class RollerRigResult:
    """Everything a command writes."""

    stem: str
    session: Session
    spec: RollerRigSpec
    options: Any  # the RollerRigOptions of the run (pipelines.roller_rig)
    time: np.ndarray
    omega_w: np.ndarray  # measured, rad/s
    omega_r: np.ndarray
    torque: np.ndarray  # request, N m
    normal_force: np.ndarray  # N
    creep_force: np.ndarray  # of the first guess's states, N
    creepage: np.ndarray
    naive_mm: np.ndarray  # omega_r R_r / omega_w, mm
    free: np.ndarray  # bool masks
    traction: np.ndarray
    runs: tuple[GuessRun, ...]
    supply_hz: float
    supply_source: str
    reference_mm: float | None
    summary: dict[str, Any]

