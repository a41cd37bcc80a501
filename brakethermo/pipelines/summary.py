"""Per-lap summary of an estimate (summary.json of OUTPUTS.md)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from brakethermo.io.session import GRID_DT, Lap


def _finite_or_none(x: float) -> float | None:
    return round(float(x), 3) if np.isfinite(x) else None


def lap_summaries(
    frame: pd.DataFrame, laps: tuple[Lap, ...], window_c: tuple[float, float]
) -> list[dict[str, Any]]:
    """One record per lap: lap time, peaks per spot, time vs the operating window.

    Parameters
    ----------
    frame : pandas.DataFrame
        The estimate table (``time``, ``lap``, ``spot1..4``, ``contact_avg``), degC.
    laps : tuple of Lap
        The session's laps (lap times from the beacons).
    window_c : (float, float) — degC
        Operating window; time is counted on the contact-band average.
    """
    lo, hi = window_c
    lap_col = frame["lap"].to_numpy()
    time = frame["time"].to_numpy()
    contact = frame["contact_avg"].to_numpy()
    records = []
    for lap in laps:
        sel = lap_col == lap.lap
        if not sel.any():
            continue
        peaks = {}
        for i in range(1, 5):
            vals = frame[f"spot{i}"].to_numpy()[sel]
            if np.isfinite(vals).any():
                j = int(np.nanargmax(vals))
                peaks[f"spot{i}"] = {
                    "temp_c": _finite_or_none(vals[j]),
                    "time_s": round(float(time[sel][j]), 1),
                }
        c = contact[sel]
        records.append(
            {
                "lap": int(lap.lap),
                "lap_time_s": round(float(lap.duration_s), 3),
                "start_s": round(float(lap.start_s), 1),
                "peak": peaks,
                "time_below_window_s": round(float(np.sum(c < lo) * GRID_DT), 1),
                "time_in_window_s": round(float(np.sum((c >= lo) & (c <= hi)) * GRID_DT), 1),
                "time_above_window_s": round(float(np.sum(c > hi) * GRID_DT), 1),
                "mean_contact_c": _finite_or_none(np.nanmean(c)),
            }
        )
    return records
