"""Scoring estimates against simulator truth (benchmarks and tests only).

The estimator never reads truth; this module is the one place where an estimate and a
``<stem>.truth.parquet`` meet, to measure accuracy on sessions the tuning did not see.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from brakethermo.pipelines import scoring

SPOTS = ("spot1", "spot2", "spot3", "spot4")


def read_truth(path: str | Path) -> pd.DataFrame:
    """The truth table (10 Hz grid, degC, W, W/(m² K))."""
    return pq.read_table(path).to_pandas()


def read_truth_params(path: str | Path) -> dict[str, Any]:
    """The truth model's own parameters (effect strengths, k_z, brake-chain errors)."""
    return json.loads(pq.read_schema(path).metadata[b"brakethermo_truth"])


def score_against_truth(
    estimate: pd.DataFrame,
    truth: pd.DataFrame,
    measured: np.ndarray,
    open_loop: np.ndarray | None = None,
    filtered: np.ndarray | None = None,
    measured_spot: int = 3,
) -> dict[str, Any]:
    """Tables 3/4 against the true face temperatures, peak errors and band coverage.

    Parameters
    ----------
    estimate : pandas.DataFrame
        ``estimate.parquet`` table (``spot1..4``, ``spot1..4_std``, ``contact_avg`` and
        its ``_std``: the contact band's coverage is scored against the true spots 2-4).
    truth : pandas.DataFrame
        Truth table with ``spot1..4`` and ``q_brake``.
    measured : ndarray (K,) — degC
        The measured spot (the single-spot baseline copies it to every spot).
    open_loop, filtered : ndarray (K, 4), optional — degC
    measured_spot : int
    """
    n = min(len(estimate), len(truth))
    if not np.allclose(estimate["time"].to_numpy()[:n], truth["time"].to_numpy()[:n]):
        raise ValueError("estimate and truth are not on the same time grid")
    ref = truth[list(SPOTS)].to_numpy()[:n]
    est = estimate[list(SPOTS)].to_numpy()[:n]
    std = estimate[[f"{s}_std" for s in SPOTS]].to_numpy()[:n]
    methods = {"smoother": est}
    if filtered is not None:
        methods["filter"] = filtered[:n]
    if open_loop is not None:
        methods["open-loop 1D-FE"] = open_loop[:n]
    methods["single-spot"] = scoring.single_spot_baseline(measured[:n])
    rows = {name: scoring.score_method(name, arr, ref) for name, arr in methods.items()}
    base = rows["single-spot"]
    braking = truth["q_brake"].to_numpy()[:n] > 0.01 * truth["q_brake"].max()
    return {
        "reference": "truth",
        "table": [r.as_dict() for r in rows.values()],
        "contact_ratio": {
            k: scoring.ratio(r.contact_rmse, base.contact_rmse) for k, r in rows.items()
        },
        "peak_spot3": scoring.peak_errors(est[:, 2], ref[:, 2], braking),
        "coverage95": {
            s: scoring.coverage(est[:, i], std[:, i], ref[:, i]) for i, s in enumerate(SPOTS)
        },
        "coverage95_contact": scoring.coverage(
            estimate["contact_avg"].to_numpy()[:n], estimate["contact_avg_std"].to_numpy()[:n],
            ref[:, 1:4].mean(axis=1)),
        "measured_spot": measured_spot,
    }
