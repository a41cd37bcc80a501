"""Per-lap summary of an estimate (summary.json of OUTPUTS.md), and the one definition of
the names and counts every output shares: lap labels, lap counts, rounding of temperatures.

Console tables, HTML pages, summary.json and the batch index all go through these, so
an out-lap is called the same everywhere, a 5-lap session has 5 laps everywhere, and a
peak of 699.46 °C shows as the same integer everywhere.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
import pandas as pd

from brakethermo.io.session import Lap

OUT_LAP = "out-lap"
SPOTS = ("spot1", "spot2", "spot3", "spot4")


def lap_label(lap: int) -> str:
    """How a lap is named to people: ``out-lap`` for lap 0, else its number."""
    return OUT_LAP if int(lap) == 0 else str(int(lap))


def lap_name(lap: int) -> str:
    """A lap in a sentence or a title: ``out-lap`` or ``lap 3``."""
    return OUT_LAP if int(lap) == 0 else f"lap {int(lap)}"


def lap_folder(lap: int) -> str:
    """The report folder of a lap (OUTPUTS.md ``lap_<NN>``)."""
    return f"lap_{int(lap):02d}"


def flying_laps(laps: Iterable[int]) -> int:
    """Laps of a session as every output counts them: the flying laps, not the out-lap."""
    return sum(1 for lap in {int(v) for v in laps} if lap >= 1)


def round_temp(x: float | None) -> float | None:
    """A temperature to 0.1 degC, half away from zero (batch JSON; the step before display)."""
    if x is None or not math.isfinite(x):
        return None
    return math.copysign(math.floor(abs(float(x)) * 10.0 + 0.5) / 10.0, x)


def temp_text(x: float | None) -> str:
    """A temperature as shown (tables, pages): the integer of :func:`round_temp`.

    Rounding to 0.1 degC first, then to the integer, gives every output the same integer
    whether it starts from the raw estimate, from summary.json (0.001 degC) or from the
    batch JSON (0.1 degC): 699.46 shows as 700 everywhere.
    """
    r = round_temp(x)
    return "–" if r is None else str(int(math.copysign(math.floor(abs(r) + 0.5), r)))


SHORT_LAP = 0.8  # a flying lap under this share of the typical one is partial (cut, in-lap)
SLOW_LAP = 1.25  # a whole lap over this share of the typical one is slow (in-lap, cool-down)


def whole_flying_laps(laps: tuple[Lap, ...]) -> set[int]:
    """The flying laps that are whole (no out-lap, no :func:`partial_laps`)."""
    partial = partial_laps(laps)
    return {lap.lap for lap in laps if lap.lap >= 1 and lap.lap not in partial}


def partial_laps(laps: tuple[Lap, ...]) -> set[int]:
    """Flying laps shorter than :data:`SHORT_LAP` of the typical flying lap: the session
    ended in them, or the rider came in — their times and peaks are not a lap's — and a
    lap the log began inside (:attr:`Lap.cut_start`) or ended inside short of a lap's
    distance (:attr:`Lap.cut_end`). The
    typical lap is the median of three or more; of two, the longer one, and only the last
    lap can then be the short one (a log cut short); one lap alone cannot be judged."""
    # the log began inside it (lap 0), or ended inside it short of a lap's distance
    cut = {lap.lap for lap in laps if lap.cut_start or lap.cut_end}
    flying = {lap.lap: lap.duration_s for lap in laps
              if lap.lap >= 1 and lap.duration_s > 0 and lap.lap not in cut}
    if len(flying) < 2:
        return cut
    if len(flying) == 2:
        first, last = sorted(flying)
        return cut | ({last} if flying[last] < SHORT_LAP * flying[first] else set())
    typical = float(np.median(list(flying.values())))
    return cut | {n for n, d in flying.items() if d < SHORT_LAP * typical}


def slow_laps(laps: tuple[Lap, ...]) -> dict[int, float]:
    """Whole laps after the out-lap over :data:`SLOW_LAP` of the typical one (the median
    of three or more), each with its share of it: an in-lap or a cool-down lap — data for
    the model like any other, but no flying lap."""
    short = partial_laps(laps)
    whole = {lap.lap: lap.duration_s for lap in laps
             if lap.lap >= 1 and lap.duration_s > 0 and lap.lap not in short}
    if len(whole) < 3:
        return {}
    typical = float(np.median(list(whole.values())))
    return {n: d / typical for n, d in whole.items() if d > SLOW_LAP * typical}


def lap_time_text(seconds: float | None) -> str:
    """A lap time as every output shows it: ``m:ss.sss`` from the beacon's lap duration."""
    if seconds is None or not math.isfinite(seconds):
        return "–"
    ms = math.floor(float(seconds) * 1000.0 + 0.5)
    minutes, rest = divmod(ms, 60_000)
    return f"{minutes}:{rest / 1000.0:06.3f}"


def _finite_or_none(x: float) -> float | None:
    return round(float(x), 3) if np.isfinite(x) else None


def node_columns(frame: pd.DataFrame) -> list[str]:
    """The ``node_<k>`` columns of an estimate frame, in node order."""
    cols = [c for c in frame.columns if c.startswith("node_") and c[5:].isdigit()]
    return sorted(cols, key=lambda c: int(c[5:]))


def hottest_radius(frame: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Temperature of the hottest face node at each step and its node index (-1: none).

    The contact-band average hides a hot edge (pad-pressure asymmetry); the operating
    window is judged on this as well.
    """
    cols = node_columns(frame)
    if not cols:
        n = len(frame)
        return np.full(n, np.nan), np.full(n, -1)
    nodes = frame[cols].to_numpy(dtype=float)
    finite = np.isfinite(nodes).any(axis=1)
    idx = np.where(finite, np.argmax(np.where(np.isfinite(nodes), nodes, -np.inf), axis=1), -1)
    hot = np.where(finite, nodes[np.arange(len(nodes)), np.maximum(idx, 0)], np.nan)
    return hot, idx


def lap_stats(
    estimate: pd.DataFrame, window_c: tuple[float, float], node_radii: np.ndarray | None = None
) -> pd.DataFrame:
    """Per-lap statistics of an estimate frame: the one computation behind summary.json's
    ``laps`` (:func:`lap_summaries`) and the lap pages.

    Returns
    -------
    DataFrame indexed by lap
        ``start_s`` (first sample of the lap, session time, s), ``lap_time_s`` (from the
        samples, s), ``peak_spot1..4`` (degC), ``peak_spot1..4_t`` (lap time of the peak,
        s), ``above_spot1..4_s`` (each spot above the window, s), ``peak_contact``,
        ``mean_contact`` (degC), ``below_s``, ``inside_s``, ``above_s`` (contact band vs
        the window, s), ``below_band_lo_s`` .. ``above_band_hi_s`` (the least and most time
        below / above the window within the contact band's 95 % band, s; with
        ``contact_avg_std`` only), ``inside_pct`` (% of the lap), ``finite_spot1..4`` (the lap has
        a finite value of that spot), ``peak_hot`` (hottest radius,
        degC), ``peak_hot_t`` (lap time of it, s), ``peak_hot_radius_mm`` (where, NaN
        without radii), ``above_hot_s`` (hottest radius above the window, s) and, with
        ``hottest_radius_std``, ``above_hot_band_lo_s`` / ``above_hot_band_hi_s`` (the
        hottest radius above the window at the low / high end of its 95 % band, s).
    """
    time = estimate["time"].to_numpy(dtype=float)
    dt = float(np.median(np.diff(time))) if len(time) > 1 else 0.1
    lo, hi = window_c
    contact = estimate["contact_avg"].to_numpy(dtype=float)
    hot, hot_idx = hottest_radius(estimate)
    radii_mm = (
        np.asarray(node_radii, dtype=float) * 1e3 if node_radii is not None
        else np.full(max(len(node_columns(estimate)), 1), np.nan)
    )
    start = estimate.groupby("lap")["time"].transform("min").to_numpy()
    work = pd.DataFrame(
        {
            "lap": estimate["lap"].to_numpy(),
            "t": time - start,
            "start": start,
            "contact": contact,
            "below": (contact < lo) * dt,
            "above": (contact > hi) * dt,
            "inside": ((contact >= lo) & (contact <= hi)) * dt,
            "hot": hot,
            "hot_r": np.where(hot_idx >= 0, radii_mm[np.maximum(hot_idx, 0)], np.nan),
            "above_hot": (hot > hi) * dt,
            **{s: estimate[s].to_numpy(dtype=float) for s in SPOTS},
            **{f"above_{s}": (estimate[s].to_numpy(dtype=float) > hi) * dt for s in SPOTS},
            **{f"finite_{s}": np.isfinite(estimate[s].to_numpy(dtype=float)) for s in SPOTS},
        }
    )
    _band_times(work, estimate, window_c, dt)
    g = work.groupby("lap", sort=True)
    out = pd.DataFrame({"start_s": g["start"].first(), "lap_time_s": g["t"].max() + dt})
    for s in SPOTS:
        out[f"peak_{s}"] = g[s].max()
        idx = work[s].fillna(-np.inf).groupby(work["lap"]).idxmax()
        out[f"peak_{s}_t"] = work.loc[idx.to_numpy(), "t"].to_numpy()
        out[f"above_{s}_s"] = g[f"above_{s}"].sum()
        out[f"finite_{s}"] = g[f"finite_{s}"].any()
    out["peak_hot"] = g["hot"].max()
    hot_at = work["hot"].fillna(-np.inf).groupby(work["lap"]).idxmax()
    out["peak_hot_t"] = work.loc[hot_at.to_numpy(), "t"].to_numpy()
    out["peak_hot_radius_mm"] = work.loc[hot_at.to_numpy(), "hot_r"].to_numpy()
    out["above_hot_s"] = g["above_hot"].sum()
    out["peak_contact"] = g["contact"].max()
    out["mean_contact"] = g["contact"].mean()
    out["below_s"] = g["below"].sum()
    out["above_s"] = g["above"].sum()
    out["inside_s"] = g["inside"].sum()
    for c in ("below_band_lo", "below_band_hi", "above_band_lo", "above_band_hi",
              "above_hot_band_lo", "above_hot_band_hi"):
        if c in work:
            out[f"{c}_s"] = g[c].sum()
    out["inside_pct"] = 100.0 * out["inside_s"] / out["lap_time_s"]
    out.index.name = "lap"
    return out


def _band_times(work: pd.DataFrame, estimate: pd.DataFrame, window_c: tuple[float, float],
                dt: float) -> None:
    """Time per step (s) below / above the window at the low and high ends of the contact
    band's and the hottest radius's 95 % bands, into ``work``: the estimate's own time
    outside the window is one draw of it, the band says how sure."""
    lo, hi = window_c
    if "contact_avg_std" in estimate:
        band = 1.96 * estimate["contact_avg_std"].to_numpy(dtype=float)
        contact = work["contact"].to_numpy()
        work["below_band_lo"] = (contact + band < lo) * dt
        work["below_band_hi"] = (contact - band < lo) * dt
        work["above_band_lo"] = (contact - band > hi) * dt
        work["above_band_hi"] = (contact + band > hi) * dt
    if "hottest_radius_std" in estimate:
        spread = 1.96 * estimate["hottest_radius_std"].to_numpy(dtype=float)
        hot = work["hot"].to_numpy()
        work["above_hot_band_lo"] = (hot - spread > hi) * dt
        work["above_hot_band_hi"] = (hot + spread > hi) * dt


def lap_summaries(
    frame: pd.DataFrame, laps: tuple[Lap, ...], window_c: tuple[float, float],
    node_radii: np.ndarray | None = None,
) -> list[dict[str, Any]]:
    """One record per lap (summary.json): lap time, peaks per spot, time vs the window.

    The figures are :func:`lap_stats`'s; here the lap time is the beacon's and a peak's
    time is session time (the lap pages give it from the lap's start).

    Parameters
    ----------
    frame : pandas.DataFrame
        The estimate table (``time``, ``lap``, ``spot1..4``, ``contact_avg``,
        ``node_<k>``), degC.
    laps : tuple of Lap
        The session's laps (lap times from the beacons).
    window_c : (float, float) — degC
        Operating window; time is counted on the contact-band average, on each spot and
        on the hottest radius.
    node_radii : ndarray — m, optional
        Radius of each ``node_<k>``, to report where the hottest radius lies.
    """
    stats = lap_stats(frame, window_c, node_radii)
    partial = partial_laps(laps)
    records = []
    for lap in laps:
        if lap.lap not in stats.index:
            continue
        row = stats.loc[lap.lap]
        peaks = {s: {"temp_c": _finite_or_none(row[f"peak_{s}"]),
                     "time_s": round(float(row["start_s"] + row[f"peak_{s}_t"]), 1)}
                 for s in SPOTS if row[f"finite_{s}"]}
        record: dict[str, Any] = {
            "lap": int(lap.lap),
            "label": lap_label(lap.lap),
            "lap_time_s": round(float(lap.duration_s), 3),
            "partial": lap.lap in partial,
            "start_s": round(float(lap.start_s), 1),
            "peak": peaks,
            "time_below_window_s": round(float(row["below_s"]), 1),
            "time_in_window_s": round(float(row["inside_s"]), 1),
            "time_above_window_s": round(float(row["above_s"]), 1),
            "time_above_window_by_spot_s": {s: round(float(row[f"above_{s}_s"]), 1)
                                            for s in peaks},
            "mean_contact_c": _finite_or_none(row["mean_contact"]),
        }
        if "above_band_lo_s" in row:
            for side in ("below", "above"):
                record[f"time_{side}_window_band_s"] = [
                    round(float(row[f"{side}_band_lo_s"]), 1),
                    round(float(row[f"{side}_band_hi_s"]), 1)]
        if np.isfinite(row["peak_hot"]):
            r_mm = row["peak_hot_radius_mm"]
            record["hottest"] = {
                "temp_c": _finite_or_none(row["peak_hot"]),
                "time_s": round(float(row["start_s"] + row["peak_hot_t"]), 1),
                "radius_mm": round(float(r_mm), 1) if np.isfinite(r_mm) else None,
                "time_above_window_s": round(float(row["above_hot_s"]), 1),
            }
            if "above_hot_band_lo_s" in row:
                record["hottest"]["time_above_window_band_s"] = [
                    round(float(row["above_hot_band_lo_s"]), 1),
                    round(float(row["above_hot_band_hi_s"]), 1)]
        records.append(record)
    return records
