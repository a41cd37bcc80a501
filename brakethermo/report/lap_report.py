"""Per-lap HTML reports and the session index, from an estimate frame and its session.

Layout (OUTPUTS.md): ``<out>/lap_<NN>/index.html`` with the figures embedded as
base64 PNG (the page needs no network) and the same PNGs beside it for slides, and
``<out>/index.html`` linking the laps with the lap-by-lap trend.
"""

from __future__ import annotations

import base64
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
    lap_distance,
    zone_table,
)
from brakethermo.report.figures import (
    AxisScales,
    LapData,
    LapFigures,
    padded_range,
    trend_figure,
)
from brakethermo.report.page import as_number, template_environment
from brakethermo.results.laps import (
    flying_laps,
    lap_folder,
    lap_label,
    lap_name,
    lap_stats,
    lap_time_text,
    node_columns,
    partial_laps,
    temp_text,
)
from brakethermo.thermal.disc import DiscSpec, load_disc

FIGURE_ALT = {
    "spots": "spot temperatures with 1-sigma bands and the measured spot",
    "heatmap": "disc temperature across the radius over the lap",
    "contact": "contact-band average against the operating window, its 1-sigma below",
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
    """Heat-map colour range of a session: where its node temperatures lie, to ``step`` degC.

    From the 1st to the 99.9th percentile, so a few cold minutes of the out-lap do not
    spend a third of the scale on temperatures the laps never show.
    """
    finite = nodes[np.isfinite(nodes)]
    if not finite.size:
        return 0.0, 1000.0
    lo = step * np.floor(np.percentile(finite, 1.0) / step)
    hi = step * np.ceil(np.percentile(finite, 99.9) / step)
    return float(lo), float(max(hi, lo + step))


def _environment() -> Environment:
    env = template_environment(keep_trailing_newline=True)
    env.filters["temp"] = temp_text
    env.filters["laptime"] = lap_time_text
    return env


def _spot_roles(summary: dict[str, Any] | None, measured: tuple[int, ...]) -> str:
    """Which spot fed the filter and which were held out to check it (four-spot sessions)."""
    run = (summary or {}).get("run", {})
    spot = run.get("measured_spot")
    if spot is None:
        return ""
    scored = ((summary or {}).get("scores") or {}).get("coverage95", {})
    held = [i for i in measured if i != spot] or [int(k[4:]) for k in scored if k[4:].isdigit()]
    if not held:
        return f"spot {spot} measured (the filter's input)"
    listed = ", ".join(str(i) for i in held)
    if ((summary or {}).get("scores") or {}).get("in_sample"):
        return (f"spot {spot} measured (the filter's input); spot{'s' if len(held) > 1 else ''}"
                f" {listed} compare in sample (the h law was identified on this session)")
    return (f"spot {spot} measured (the filter's input); spot{'s' if len(held) > 1 else ''} "
            f"{listed} held out to check the estimate (the law identified on another"
            " session)")


def _scores_view(summary: dict[str, Any] | None) -> dict[str, Any] | None:
    """The self-scores of a four-spot session (Tables 3/4, peaks, coverage) for the page."""
    scores = (summary or {}).get("scores")
    if not scores:
        return None
    ratios = scores.get("contact_ratio_vs_single_spot", {})
    rows = [
        {**row, "ratio": ratios.get(row["method"])} for row in scores.get("table", [])
    ]
    spot = scores.get("measured_spot")
    peak = scores.get("peak", {}).get(f"spot{spot}", {})
    return {
        "rows": rows,
        "in_sample": bool(scores.get("in_sample")),
        "measured_spot": spot,
        "peak": peak,
        "peaks": scores.get("peak", {}),
        "coverage": {k: 100.0 * v for k, v in scores.get("coverage95", {}).items()
                     if v is not None},
        "coverage_written": {k: 100.0 * v
                             for k, v in scores.get("coverage95_written_band", {}).items()
                             if v is not None},
    }


def _interval(lo: float, hi: float, fmt: str = "{:.0f}") -> str:
    """'95 % lo to hi %', or why there is none (the verdict engine draws none over fewer
    than two units)."""
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "no interval: fewer than two units"
    return f"95 % {fmt.format(lo)} to {fmt.format(hi)} %"


def _on_top_text(top: dict[str, Any] | None) -> str:
    """A state's test on top of those switched on, in words ("" when it had none)."""
    if not top:
        return ""
    lo, hi = (as_number(v) for v in top.get("shrink_ci95_pct", [None] * 2))
    return (f"; on top of {', '.join(top.get('of', []))}, shrink"
            f" {as_number(top.get('shrink_pct')):.0f} % ({_interval(lo, hi)})")


def _crown_noise_text(fact: dict[str, Any]) -> str:
    """The race's choice of its crown-split noise (``online_choice.crown_noise``), in words."""
    tried = []
    for r in fact.get("tests", []):
        if r.get("failed"):
            tried.append(f"{as_number(r.get('sigma_crown')):g}: the filter failed there"
                         f" ({r['failed']})")
            continue
        lo, hi = (as_number(v) for v in r.get("loglik_gain_ci95", [None] * 2))
        tried.append(f"{as_number(r.get('sigma_crown')):g}:"
                     f" {as_number(r.get('loglik_gain_per_reading')):+.3f} nats per reading"
                     f" (95 % {lo:+.3f} to {hi:+.3f})")
    law, chosen = as_number(fact.get("law")), as_number(fact.get("chosen"))
    verdict = (f"lowered to {chosen:g} from the law's {law:g}" if fact.get("changed") else
               f"the law's {law:g} kept")
    return f"crown-split noise: {verdict} — {fact.get('test', '')}; " + "; ".join(tried)


def _decisions(summary: dict[str, Any] | None) -> list[str]:
    """The race's own choices (online states, the law's effects kept or dropped), in words."""
    choice = ((summary or {}).get("run") or {}).get("online_choice") or {}
    lines = []
    for row in choice.get("scores", []):
        lo, hi = (as_number(v) for v in row.get("shrink_ci95_pct", [None] * 2))
        verdict = "switched on" if row.get("name") in choice.get("chosen", []) else "left off"
        lines.append(f"online {row.get('name')}: {verdict} — {row.get('test', '')}, shrink"
                     f" {as_number(row.get('shrink_pct')):.0f} % ({_interval(lo, hi)})"
                     + (f"; {row['like_law']}" if row.get("like_law") else "")
                     + (f"; {row['with_uniform_crown']}" if row.get("with_uniform_crown")
                        else "")
                     + _on_top_text(row.get("on_top"))
                     + (f"; on the laps it decided on, {row['by_lap']}"
                        if row.get("by_lap") and verdict == "left off" else ""))
    for row in choice.get("law_effects_tested", []):
        name = str(row.get("name", "")).removeprefix("without ")
        lo, hi = (as_number(v) for v in row.get("shrink_ci95_pct", [None] * 2))
        verdict = ("dropped" if name in choice.get("law_effects_dropped", []) else
                   "kept")
        if "law" in row:  # the pad crown: say which weights were tested against uniform
            name = "pad-crown weights w = " + ", ".join(f"{w:.2f}" for w in row["law"])
        # an earned effect's row is the law with it against without it
        side = "with" if row.get("must_earn", row.get("earned")) else "without"  # earlier
        shrink = as_number(row.get("shrink_pct"))
        lines.append(f"the h law's {name}: {verdict} — {row.get('test', '')}"
                     + (f", error {side} it {-shrink:+.0f} % ({_interval(-hi, -lo, '{:+.0f}')})"
                        if np.isfinite(shrink) else ""))
        if row.get("said"):  # what it means for the unmeasured spots, and how to keep it
            lines.append(str(row["said"]))
    run = (summary or {}).get("run") or {}
    found = ((run.get("effects") or {}).get("slipstream") or {}).get("found")
    if found and found.get("said"):
        lines.append(str(found["said"]))
    if choice.get("layering"):
        lines.append(f"layering: {choice['layering']}")
    if choice.get("crown_noise"):
        lines.append(_crown_noise_text(choice["crown_noise"]))
    if choice.get("forced_or_from_law"):
        lines.append("forced by option or carried by the law: " + ", ".join(
            f"{k} {'on' if v else 'off'}" for k, v in choice["forced_or_from_law"].items()))
    order = run.get("filter_order") or {}
    if order.get("kind") == "reduced":
        lines.append(
            f"reduced-order filter: the {order['full_states']} filter states of this mesh on"
            f" {order['modes']} thermal modes ({order['approximation']}; snapshot projection"
            f" {order['snapshot_projection_rms_c']:.3f} °C RMS); --modes 0 runs the full one")
    return lines


def _law_view(summary: dict[str, Any] | None, out_dir: Path) -> dict[str, Any] | None:
    """The h law the estimate used (and its plot when identify-h wrote it here)."""
    run = (summary or {}).get("run", {})
    law = run.get("h_law")
    png = out_dir / "h_law.png"
    if not png.is_file() and law:
        png = Path(law).with_name("h_law.png")  # the plot identify-h wrote beside the law
    if not law and not png.is_file():
        return None
    return {
        "path": law or "",
        "choice": run.get("h_law_choice", ""),
        "png_b64": base64.b64encode(png.read_bytes()).decode("ascii") if png.is_file() else None,
    }


def _stats_with_readings(estimate: pd.DataFrame, session: Session | None, disc: DiscSpec,
                         node_radii: np.ndarray, measured: np.ndarray, zones_df: pd.DataFrame
                         ) -> pd.DataFrame:
    """Per-lap figures of the estimate, the beacon's lap times, the zone counts, and what
    the sensors read (peaks and time above the window per measured spot)."""
    stats = lap_stats(estimate, disc.window_c, node_radii)
    if session is not None and session.laps:
        # the beacon's lap time, as inspect, estimate and summary.json give it (the grid's
        # count of steps differs by up to a step)
        beacon = {lap.lap: lap.duration_s for lap in session.laps}
        stats["lap_time_s"] = [beacon.get(int(n), t) for n, t in stats["lap_time_s"].items()]
        stats["partial"] = [int(n) in partial_laps(session.laps) for n in stats.index]
    stats["zones"] = zones_df.groupby("lap").size().reindex(stats.index, fill_value=0)
    # What the sensors read beats any estimate: a measured spot above the window counts
    # even when the model (e.g. with unmodelled pad asymmetry) keeps its estimate inside.
    time = estimate["time"].to_numpy(dtype=float)
    laps_col = estimate["lap"].to_numpy()
    dt = float(np.median(np.diff(time))) if len(time) > 1 else 0.1
    for i, s in enumerate(SPOTS):
        if np.isfinite(measured[i]).any():
            reading = pd.Series(measured[i])
            stats[f"meas_peak_{s}"] = reading.groupby(laps_col).max().reindex(stats.index)
            stats[f"meas_above_{s}_s"] = (
                (reading > disc.window_c[1]).groupby(laps_col).sum().reindex(stats.index) * dt
            )
    # the hottest radius is the estimate's; a reading above it is said beside it
    meas = [c for c in stats.columns if c.startswith("meas_peak_")]
    if meas:
        peaks = stats[meas].astype(float)
        best = peaks.fillna(-np.inf).idxmax(axis=1)
        stats["meas_peak_max"] = peaks.max(axis=1)
        stats["meas_peak_spot"] = best.str.removeprefix("meas_peak_spot")
    return stats


def _lap_data(arrays: dict[str, np.ndarray], zones: np.ndarray, a: int, b: int,
              names: tuple[str, ...] = ()) -> LapData:
    """One lap's slice ``[a, b)`` of the session arrays, times from the lap's start."""
    time = arrays["time"]
    t0 = time[a]
    in_lap = (zones[:, 0] >= a) & (zones[:, 0] < b) if len(zones) else np.zeros(0, bool)
    lap_zones = zones[in_lap]
    zones_t = (
        np.column_stack((time[lap_zones[:, 0]] - t0, time[np.minimum(lap_zones[:, 1], b - 1)] - t0))
        if len(lap_zones) else np.empty((0, 2))
    )
    return LapData(
        t=time[a:b] - t0,
        spot=arrays["spot"][:, a:b],
        spot_std=arrays["spot_std"][:, a:b],
        measured=arrays["measured"][:, a:b],
        contact=arrays["contact"][a:b],
        contact_std=arrays["contact_std"][a:b],
        nodes=arrays["nodes"][:, a:b],
        speed_kmh=arrays["speed"][a:b] * KMH,
        pressure_bar=arrays["pressure"][a:b] / BAR,
        zones_t=zones_t,
        zone_names=names,
    )


def _lap_figures(arrays: dict[str, np.ndarray], laps_col: np.ndarray, disc: DiscSpec,
                 node_radii: np.ndarray, measured_spots: tuple[int, ...]) -> LapFigures:
    """The lap figures with one set of axes for the whole session."""
    # Ranges from the estimate and the readings, not the bands: a wide start-up band
    # would drag the axis far below anything the disc does.
    contact_lo, contact_hi = padded_range(arrays["contact"])
    scales = AxisScales(
        spots=padded_range(arrays["spot"], arrays["measured"]),
        contact=(min(contact_lo, disc.window_c[0] - 50.0),
                 max(contact_hi, disc.window_c[1] + 50.0)),
        speed_kmh=max(padded_range(arrays["speed"] * KMH)[1], 10.0),
        pressure_bar=max(padded_range(arrays["pressure"] / BAR)[1], 1.0),
    )
    nodes = arrays["nodes"]
    return LapFigures(
        node_radii, disc.spot_radii, disc.window_c, disc.r_int, disc.r_est, scales,
        # The flying laps set the scale; a cold out-lap shows at the bottom colour.
        temp_range_c=_colour_range(nodes[:, laps_col >= 1] if (laps_col >= 1).any() else nodes),
        measured_spots=measured_spots,
    )


def _neighbours(lap_numbers: list[int], k: int) -> dict[str, str | None]:
    """Links of lap page ``k`` to the previous and the next lap."""
    prev = lap_numbers[k - 1] if k else None
    nxt = lap_numbers[k + 1] if k + 1 < len(lap_numbers) else None
    return {
        "prev_href": f"../{lap_folder(prev)}/index.html" if prev is not None else None,
        "prev_label": lap_name(prev) if prev is not None else None,
        "next_href": f"../{lap_folder(nxt)}/index.html" if nxt is not None else None,
        "next_label": lap_name(nxt) if nxt is not None else None,
    }


def _write_lap_pages(
    figs: LapFigures, arrays: dict[str, np.ndarray], zones: np.ndarray, stats: pd.DataFrame,
    zones_df: pd.DataFrame, out_dir: Path, lap_tpl: Any, common: dict[str, Any],
    progress: Callable[[int, int], None] | None,
) -> tuple[dict[int, Path], float]:
    """One page and its figures per lap (``common``: what every page shows); the pages
    and the seconds spent drawing."""
    lap_numbers = [int(v) for v in stats.index]
    lap_of_step = arrays["lap"]
    slices = pd.Series(np.arange(len(lap_of_step))).groupby(lap_of_step).agg(["min", "max"])
    render_s = 0.0
    pages: dict[int, Path] = {}
    try:
        for k, lap in enumerate(lap_numbers):
            a, b = int(slices.loc[lap, "min"]), int(slices.loc[lap, "max"]) + 1
            r0 = _time.perf_counter()
            names = tuple(zones_df.loc[zones_df["lap"] == lap, "zone"])
            pngs = figs.render(_lap_data(arrays, zones, a, b, names))
            render_s += _time.perf_counter() - r0
            lap_dir = out_dir / lap_folder(lap)
            for fig_name, png in pngs.items():
                write_bytes_atomic(lap_dir / f"{fig_name}.png", png)
            html = lap_tpl.render(
                **common,
                lap_title=lap_name(lap),
                stats=stats.loc[lap],
                zones=zones_df[zones_df["lap"] == lap].to_dict("records"),
                figures=[
                    {"alt": FIGURE_ALT[n], "b64": base64.b64encode(p).decode("ascii")}
                    for n, p in pngs.items()
                ],
                **_neighbours(lap_numbers, k),
            )
            pages[lap] = lap_dir / "index.html"
            write_text_atomic(pages[lap], html)
            if progress is not None:
                progress(k + 1, len(lap_numbers))
    finally:
        figs.close()
    return pages, render_s


def _zones_named(estimate: pd.DataFrame, session: Session | None, speed: np.ndarray,
                 pressure: np.ndarray, zones: np.ndarray, disc: DiscSpec) -> pd.DataFrame:
    """The zone table with each zone named by where it is on the track (as every page)."""
    time = estimate["time"].to_numpy(dtype=float)
    dt = float(np.median(np.diff(time))) if len(time) > 1 else 0.1
    logged = (_aligned(session, time, "distance")
              if session is not None and session.has("distance") else None)
    dist = lap_distance(estimate["lap"].to_numpy(), speed, dt, logged)
    return zone_table(estimate, speed, pressure, zones, disc.window_c, dist)


def write_session_report(
    estimate: pd.DataFrame,
    session: Session | None,
    out_dir: str | Path,
    *,
    node_radii: np.ndarray | None = None,
    disc: DiscSpec | None = None,
    name: str | None = None,
    detection: ZoneDetection | None = None,
    summary: dict[str, Any] | None = None,
    progress: Callable[[int, int], None] | None = None,
    back_href: str | None = None,
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
    summary : dict, optional
        The estimate's ``summary.json``: the measured spot, the self-scores of a
        four-spot session and the h law used go on the session page.
    progress : callable, optional
        ``progress(laps_done, laps_total)`` after each lap page.
    back_href : str, optional
        Link from the session page up to an index of sessions (batch: ``../index.html``).
    """
    t_start = _time.perf_counter()
    out_dir = Path(out_dir)
    disc = disc if disc is not None else _session_disc(session)
    detection = detection or ZoneDetection()
    name = name or (session.path.stem if session is not None else out_dir.name)
    nodes_cols = node_columns(estimate)
    if node_radii is None:
        node_radii = np.linspace(disc.r_int, disc.r_est, len(nodes_cols))

    grid = _grid_channels(estimate, session)
    zones = detect_zones(grid["time"], grid["pressure"], detection)
    zones_df = _zones_named(estimate, session, grid["speed"], grid["pressure"], zones, disc)
    stats = _stats_with_readings(estimate, session, disc, node_radii, grid["measured"], zones_df)

    env = _environment()
    measured_spots = _measured_spots(grid["measured"])
    texts = _session_texts(name, session, disc, len(nodes_cols), summary, measured_spots)
    arrays = _session_arrays(estimate, nodes_cols, grid)

    figs = _lap_figures(arrays, grid["lap"], disc, node_radii, measured_spots)
    pages, render_s = _write_lap_pages(
        figs, arrays, zones, stats, zones_df, out_dir, env.get_template("lap.html.j2"),
        _lap_common(texts, detection, stats), progress)

    index = _write_index(
        env, out_dir, texts.name, texts.facts, texts.window, texts.footer, stats, disc,
        extras={"spot_roles": texts.spot_roles, "scores": _scores_view(summary),
                "law": _law_view(summary, out_dir), "back_href": back_href,
                "decisions": _decisions(summary)},
    )  # fmt: skip
    total = _time.perf_counter() - t_start
    return ReportResult(
        index=index,
        lap_pages=pages,
        laps=stats,
        zones=zones_df,
        timings={"render_s": render_s, "write_s": total - render_s, "total_s": total},
    )


def _session_disc(session: Session | None) -> DiscSpec:
    """The disc of the session's ``disc`` fact, else the default disc."""
    disc_id = session.metadata.get("disc") if session is not None else None
    return load_disc(disc_id or "cc-340-8")


def _grid_channels(estimate: pd.DataFrame, session: Session | None) -> dict[str, np.ndarray]:
    """The estimate's ``time`` (s) and ``lap``, and the session's ``speed`` (m/s), front
    brake ``pressure`` (Pa) and ``measured`` spots (degC, (4, n)) on that grid."""
    time = estimate["time"].to_numpy(dtype=float)
    laps_col = estimate["lap"].to_numpy()
    speed = _aligned(session, time, "speed")
    pressure = _aligned(session, time, "brake_pressure_front")
    measured = _measured(session, time)
    return {"time": time, "lap": laps_col, "measured": measured, "speed": speed,
            "pressure": pressure}


def _measured_spots(measured: np.ndarray) -> tuple[int, ...]:
    """The spots (1..4) the session measured anywhere, from the (4, n) readings."""
    return tuple(int(i) + 1 for i in np.flatnonzero(np.isfinite(measured).any(axis=1)))


@dataclass(frozen=True)
class _SessionTexts:
    """What every page of a session says of it.

    Attributes
    ----------
    name : str
        Title of the pages.
    facts : str
        Vehicle, track, date and disc (:func:`_facts`).
    window : str
        The disc's operating window, degC.
    spot_roles : str
        Which spot fed the filter, which check it (:func:`_spot_roles`).
    footer : str
        Version, disc and node count.
    """

    name: str
    facts: str
    window: str
    spot_roles: str
    footer: str


def _session_texts(name: str, session: Session | None, disc: DiscSpec, n_nodes: int,
                   summary: dict[str, Any] | None, measured_spots: tuple[int, ...]
                   ) -> _SessionTexts:
    """The texts of :class:`_SessionTexts` for this session and disc."""
    return _SessionTexts(
        name=name,
        window=f"{disc.window_c[0]:.0f}–{disc.window_c[1]:.0f} °C",
        facts=_facts(session),
        spot_roles=_spot_roles(summary, measured_spots),
        footer=f"brakethermo {__version__} · disc {disc.id} · {n_nodes} nodes",
    )


def _lap_common(texts: _SessionTexts, detection: ZoneDetection,
                stats: pd.DataFrame) -> dict[str, Any]:
    """What every lap page shows besides its lap: the session's texts, the zone threshold
    (bar) and the spots whose readings the stats carry."""
    return {"session_name": texts.name, "facts": texts.facts, "spot_roles": texts.spot_roles,
            "window": texts.window, "zone_threshold_bar": detection.on_pa / BAR,
            "footer": texts.footer,
            "measured_keys": [s for s in SPOTS if f"meas_above_{s}_s" in stats]}


def _session_arrays(estimate: pd.DataFrame, nodes_cols: list[str],
                    grid: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays the lap pages slice: the grid channels (:func:`_grid_channels`) and the
    estimate's spots, contact band and nodes (degC), spot-major."""
    return {**grid,
            "spot": estimate[list(SPOTS)].to_numpy(dtype=float).T,
            "spot_std": estimate[[f"{s}_std" for s in SPOTS]].to_numpy(dtype=float).T,
            "contact": estimate["contact_avg"].to_numpy(dtype=float),
            "contact_std": estimate["contact_avg_std"].to_numpy(dtype=float),
            "nodes": estimate[nodes_cols].to_numpy(dtype=float).T}


def _write_index(
    env: Environment,
    out_dir: Path,
    name: str,
    facts: str,
    window: str,
    footer: str,
    stats: pd.DataFrame,
    disc: DiscSpec,
    extras: dict[str, Any] | None = None,
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
        {**row, "label": lap_label(int(lap)), "href": f"{lap_folder(int(lap))}/index.html"}
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
        flying_laps=flying_laps(int(v) for v in laps),
        has_out_lap=bool((laps == 0).any()),
        partial_labels=[f"lap {r['label']}" for r in rows
                        if r.get("partial") and r["label"] != "out-lap"],
        hottest=hottest,
        **(extras or {}),
        session_inside_pct=session_inside,
        trend_b64=base64.b64encode(png).decode("ascii"),
    )
    index = out_dir / "index.html"
    write_text_atomic(index, html)
    return index
