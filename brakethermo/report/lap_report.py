"""Per-lap HTML reports and the session index, from an estimate frame and its session.

Layout (OUTPUTS.md): ``<out>/lap_<NN>/index.html`` with the figures embedded as
base64 PNG (the page needs no network) and the same PNGs beside it for slides, and
``<out>/index.html`` linking the laps with the lap-by-lap trend.
"""

from __future__ import annotations

import base64
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
from jinja2 import Environment

from brakethermo import __version__
from brakethermo.io.atomic import write_bytes_atomic, write_text_atomic
from brakethermo.io.session import Session
from brakethermo.report.braking_zones import (
    BAR,
    KMH,
    SPOTS,
    ZoneDetection,
    detect_zones,
    zone_table,
)
from brakethermo.report.figures import (
    AxisScales,
    LapData,
    LapFigures,
    padded_range,
    trend_figure,
)
from brakethermo.report.page import template_environment
from brakethermo.thermal.disc import DiscSpec, load_disc

FIGURE_ALT = {
    "spots": "spot temperatures with 1-sigma bands and the measured spot",
    "heatmap": "disc temperature across the radius over the lap",
    "contact": "contact-band average against the operating window",
    "context": "speed and front brake pressure",
}


@dataclass(frozen=True)
class ReportResult:
    """What :func:`write_session_report` wrote.

    Attributes
    ----------
    index : Path
        The session index page.
    lap_pages : dict of int to Path
        Report page of each lap.
    laps : DataFrame
        Per-lap statistics (:func:`lap_stats`).
    zones : DataFrame
        Braking-zone table of the whole session (:func:`zone_table`).
    timings : dict of str to float — s
        ``render_s`` (drawing the figures), ``write_s`` (HTML and files), ``total_s``.
    """

    index: Path
    lap_pages: dict[int, Path]
    laps: pd.DataFrame
    zones: pd.DataFrame
    timings: dict[str, float] = field(default_factory=dict)


def read_estimate(path: str | Path) -> tuple[pd.DataFrame, np.ndarray | None]:
    """Read an ``estimate.parquet`` and the node radii from its field metadata.

    Returns
    -------
    frame : DataFrame
    node_radii : ndarray — m, or None when a node column carries no ``radius_m``.
    """
    table = pq.read_table(path)
    radii = []
    for f in table.schema:
        if f.name.startswith("node_"):
            meta = f.metadata or {}
            if b"radius_m" not in meta:
                return table.to_pandas(), None
            radii.append(float(meta[b"radius_m"]))
    return table.to_pandas(), np.asarray(radii)


def node_columns(frame: pd.DataFrame) -> list[str]:
    """The ``node_<k>`` columns of an estimate frame, in node order."""
    cols = [c for c in frame.columns if c.startswith("node_") and c[5:].isdigit()]
    return sorted(cols, key=lambda c: int(c[5:]))


def lap_stats(estimate: pd.DataFrame, window_c: tuple[float, float]) -> pd.DataFrame:
    """Per-lap statistics of an estimate frame.

    Returns
    -------
    DataFrame indexed by lap
        ``lap_time_s``, ``peak_spot1..4`` (degC), ``peak_spot1..4_t`` (lap time of the
        peak, s), ``peak_contact``, ``mean_contact`` (degC), ``below_s``, ``inside_s``,
        ``above_s`` (contact band vs the window, s), ``inside_pct`` (% of the lap).
    """
    time = estimate["time"].to_numpy(dtype=float)
    dt = float(np.median(np.diff(time))) if len(time) > 1 else 0.1
    lo, hi = window_c
    contact = estimate["contact_avg"].to_numpy(dtype=float)
    lap_time = time - estimate.groupby("lap")["time"].transform("min").to_numpy()
    work = pd.DataFrame(
        {
            "lap": estimate["lap"].to_numpy(),
            "t": lap_time,
            "contact": contact,
            "below": (contact < lo) * dt,
            "above": (contact > hi) * dt,
            "valid": np.isfinite(contact) * dt,
            **{s: estimate[s].to_numpy(dtype=float) for s in SPOTS},
        }
    )
    g = work.groupby("lap", sort=True)
    out = pd.DataFrame({"lap_time_s": g["t"].max() + dt})
    for s in SPOTS:
        out[f"peak_{s}"] = g[s].max()
        idx = work[s].fillna(-np.inf).groupby(work["lap"]).idxmax()
        out[f"peak_{s}_t"] = work.loc[idx.to_numpy(), "t"].to_numpy()
    out["peak_contact"] = g["contact"].max()
    out["mean_contact"] = g["contact"].mean()
    out["below_s"] = g["below"].sum()
    out["above_s"] = g["above"].sum()
    out["inside_s"] = g["valid"].sum() - out["below_s"] - out["above_s"]
    out["inside_pct"] = 100.0 * out["inside_s"] / out["lap_time_s"]
    out.index.name = "lap"
    return out


def _aligned(session: Session | None, time: np.ndarray, name: str) -> np.ndarray:
    """Session channel ``name`` on the estimate's time grid (NaN where absent)."""
    if session is None or name not in session.frame.columns:
        return np.full(time.shape, np.nan)
    s_time = session.frame["time"].to_numpy(dtype=float)
    values = session.frame[name].to_numpy(dtype=float)
    if s_time.shape == time.shape and np.allclose(s_time, time):
        return values
    # Both sit on the 10 Hz grid of OUTPUTS.md; match by grid index.
    key = np.rint(s_time * 10.0).astype(np.int64)
    want = np.rint(time * 10.0).astype(np.int64)
    pos = np.searchsorted(key, want)
    pos = np.clip(pos, 0, len(key) - 1)
    out = values[pos]
    out[key[pos] != want] = np.nan
    return out


def _measured(session: Session | None, time: np.ndarray) -> np.ndarray:
    """Measured spot temperatures (4, n): race sessions have only spot 3 (``disc_temp``)."""
    meas = np.stack([_aligned(session, time, f"disc_temp_spot{i}") for i in range(1, 5)])
    if not np.isfinite(meas[2]).any():
        meas[2] = _aligned(session, time, "disc_temp")
    return meas


def _facts(session: Session | None) -> str:
    if session is None:
        return ""
    keys = ("vehicle", "track", "date", "disc")
    return " · ".join(str(session.metadata[k]) for k in keys if session.metadata.get(k))


def _colour_range(nodes: np.ndarray, step: float = 50.0) -> tuple[float, float]:
    """Heat-map colour range of a session: its node temperatures, out to ``step`` degC."""
    if not np.isfinite(nodes).any():
        return 0.0, 1000.0
    lo = step * np.floor(np.nanmin(nodes) / step)
    hi = step * np.ceil(np.nanmax(nodes) / step)
    return float(lo), float(max(hi, lo + step))


def _environment() -> Environment:
    return template_environment(keep_trailing_newline=True)


def _lap_label(lap: int) -> str:
    return f"{lap:02d}"


def write_session_report(
    estimate: pd.DataFrame,
    session: Session | None,
    out_dir: str | Path,
    *,
    node_radii: np.ndarray | None = None,
    disc: DiscSpec | None = None,
    name: str | None = None,
    detection: ZoneDetection | None = None,
) -> ReportResult:
    """Write the per-lap reports and the session index into ``out_dir``.

    Parameters
    ----------
    estimate : DataFrame
        Estimate frame of OUTPUTS.md (``time``, ``lap``, ``spot1..4``,
        ``spot1..4_std``, ``contact_avg``, ``contact_avg_std``, ``node_<k>``).
    session : Session or None
        The session the estimate came from, for the measured spot, speed and brake
        pressure; without it those are left out of the figures.
    out_dir : path
        The session's output directory (``OUT/<stem>``); ``lap_<NN>/`` go inside.
    node_radii : ndarray — m, optional
        Radius of each ``node_<k>``; evenly spread over the ring when not given.
    disc : DiscSpec, optional
        Datasheet (spot radii, ring radii, window); the session's ``disc`` fact or the
        default disc when not given.
    name : str, optional
        Title of the pages; the session file stem by default.
    detection : ZoneDetection, optional
        Braking-zone thresholds.
    """
    t_start = _time.perf_counter()
    out_dir = Path(out_dir)
    if disc is None:
        disc_id = session.metadata.get("disc") if session is not None else None
        disc = load_disc(disc_id or "cc-340-8")
    detection = detection or ZoneDetection()
    name = name or (session.path.stem if session is not None else out_dir.name)
    nodes_cols = node_columns(estimate)
    if node_radii is None:
        node_radii = np.linspace(disc.r_int, disc.r_est, len(nodes_cols))

    time = estimate["time"].to_numpy(dtype=float)
    laps_col = estimate["lap"].to_numpy()
    speed = _aligned(session, time, "speed")
    pressure = _aligned(session, time, "brake_pressure_front")
    measured = _measured(session, time)
    spot = estimate[list(SPOTS)].to_numpy(dtype=float).T
    spot_std = estimate[[f"{s}_std" for s in SPOTS]].to_numpy(dtype=float).T
    contact = estimate["contact_avg"].to_numpy(dtype=float)
    contact_std = estimate["contact_avg_std"].to_numpy(dtype=float)
    nodes = estimate[nodes_cols].to_numpy(dtype=float).T

    zones = detect_zones(time, pressure, detection)
    zones_df = zone_table(estimate, speed, pressure, zones, disc.window_c)
    stats = lap_stats(estimate, disc.window_c)
    stats["zones"] = zones_df.groupby("lap").size().reindex(stats.index, fill_value=0)

    env = _environment()
    lap_tpl = env.get_template("lap.html.j2")
    window = f"{disc.window_c[0]:.0f}–{disc.window_c[1]:.0f} °C"
    facts = _facts(session)
    footer = f"brakethermo {__version__} · disc {disc.id} · {len(nodes_cols)} nodes"
    lap_numbers = [int(v) for v in stats.index]
    lap_slices = pd.Series(np.arange(len(laps_col))).groupby(laps_col).agg(["min", "max"])

    contact_lo, contact_hi = padded_range(contact - contact_std, contact + contact_std)
    scales = AxisScales(
        spots=padded_range(spot - spot_std, spot + spot_std, measured),
        contact=(
            min(contact_lo, disc.window_c[0] - 50.0),
            max(contact_hi, disc.window_c[1] + 50.0),
        ),
        speed_kmh=max(padded_range(speed * KMH)[1], 10.0),
        pressure_bar=max(padded_range(pressure / BAR)[1], 1.0),
    )
    figs = LapFigures(
        node_radii,
        disc.spot_radii,
        disc.window_c,
        disc.r_int,
        disc.r_est,
        scales,
        temp_range_c=_colour_range(nodes),
        measured_spots=tuple(int(i) + 1 for i in np.flatnonzero(np.isfinite(measured).any(axis=1))),
    )
    render_s = 0.0
    pages: dict[int, Path] = {}
    try:
        for k, lap in enumerate(lap_numbers):
            a, b = int(lap_slices.loc[lap, "min"]), int(lap_slices.loc[lap, "max"]) + 1
            t0 = time[a]
            in_lap = (zones[:, 0] >= a) & (zones[:, 0] < b) if len(zones) else np.zeros(0, bool)
            lap_zones = zones[in_lap]
            zones_t = (
                np.column_stack(
                    (time[lap_zones[:, 0]] - t0, time[np.minimum(lap_zones[:, 1], b - 1)] - t0)
                )
                if len(lap_zones)
                else np.empty((0, 2))
            )
            data = LapData(
                t=time[a:b] - t0,
                spot=spot[:, a:b],
                spot_std=spot_std[:, a:b],
                measured=measured[:, a:b],
                contact=contact[a:b],
                contact_std=contact_std[a:b],
                nodes=nodes[:, a:b],
                speed_kmh=speed[a:b] * KMH,
                pressure_bar=pressure[a:b] / BAR,
                zones_t=zones_t,
            )
            r0 = _time.perf_counter()
            pngs = figs.render(data)
            render_s += _time.perf_counter() - r0
            lap_dir = out_dir / f"lap_{_lap_label(lap)}"
            for fig_name, png in pngs.items():
                write_bytes_atomic(lap_dir / f"{fig_name}.png", png)
            html = lap_tpl.render(
                session_name=name,
                lap_label=_lap_label(lap),
                facts=facts,
                window=window,
                stats=stats.loc[lap],
                zones=zones_df[zones_df["lap"] == lap].to_dict("records"),
                zone_threshold_bar=detection.on_pa / BAR,
                footer=footer,
                figures=[
                    {"alt": FIGURE_ALT[n], "b64": base64.b64encode(p).decode("ascii")}
                    for n, p in pngs.items()
                ],
                prev_href=(f"../lap_{_lap_label(lap_numbers[k - 1])}/index.html" if k else None),
                prev_label=_lap_label(lap_numbers[k - 1]) if k else None,
                next_href=(
                    f"../lap_{_lap_label(lap_numbers[k + 1])}/index.html"
                    if k + 1 < len(lap_numbers)
                    else None
                ),
                next_label=_lap_label(lap_numbers[k + 1]) if k + 1 < len(lap_numbers) else None,
            )
            pages[lap] = lap_dir / "index.html"
            write_text_atomic(pages[lap], html)
    finally:
        figs.close()

    index = _write_index(env, out_dir, name, facts, window, footer, stats, disc)
    total = _time.perf_counter() - t_start
    return ReportResult(
        index=index,
        lap_pages=pages,
        laps=stats,
        zones=zones_df,
        timings={"render_s": render_s, "write_s": total - render_s, "total_s": total},
    )


def _write_index(
    env: Environment,
    out_dir: Path,
    name: str,
    facts: str,
    window: str,
    footer: str,
    stats: pd.DataFrame,
    disc: DiscSpec,
) -> Path:
    laps = stats.index.to_numpy()
    png = trend_figure(
        laps,
        stats[[f"peak_{s}" for s in SPOTS]].to_numpy().T,
        stats["mean_contact"].to_numpy(),
        stats["inside_pct"].to_numpy(),
        disc.window_c,
    )
    write_bytes_atomic(out_dir / "trend.png", png)
    rows = [
        {**row, "label": _lap_label(int(lap)), "href": f"lap_{_lap_label(int(lap))}/index.html"}
        for lap, row in zip(laps, stats.to_dict("records"), strict=True)
    ]
    hottest = max(rows, key=lambda r: -np.inf if np.isnan(r["peak_contact"]) else r["peak_contact"])
    session_inside = 100.0 * stats["inside_s"].sum() / stats["lap_time_s"].sum()
    html = env.get_template("index.html.j2").render(
        session_name=name,
        facts=facts,
        window=window,
        footer=footer,
        laps=rows,
        hottest=hottest,
        session_inside_pct=session_inside,
        trend_b64=base64.b64encode(png).decode("ascii"),
    )
    index = out_dir / "index.html"
    write_text_atomic(index, html)
    return index
