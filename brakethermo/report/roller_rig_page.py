"""The roller-rig report page: radius tracks with their bands, speeds, creep, Table 1."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from brakethermo.report.page import (
    Card,
    Page,
    Section,
    TableBlock,
    consistency_text,
    number_text,
)
from brakethermo.results.rig_diagnosis import carried_text
from brakethermo.results.roller_rig import RollerRigResult

# The paper's Table 1: whole-run RMSE of the radius, mm, (under-, over-estimation).
PAPER_TABLE1 = {15: (0.6060, 0.8233), 30: (1.0631, 1.0139)}
PAPER_RADIUS_MM = 348.2  # the paper's measured radius, the base of its percentages
MAX_POINTS = 4000  # plotted points per line (the PNG cannot show more)


def _thin(n: int) -> slice:
    return slice(None, None, max(1, n // MAX_POINTS))


def paper_speed_kmh(supply_hz: float) -> int:
    """The paper's scenario closest to the roller-motor supply (7.5 Hz: 15 km/h, 15 Hz: 30)."""
    return 15 if supply_hz < 11.25 else 30


def radius_figure(result: RollerRigResult, window: tuple[float, float] | None = None) -> Figure:
    """Radius track of every guess with its 2-sigma band, the filter track, reference, naive."""
    fig = Figure(figsize=(9.0, 4.6), dpi=110)
    ax = fig.add_subplot()
    t = result.time
    sel = np.ones(t.size, bool) if window is None else (t >= window[0]) & (t <= window[1])
    idx = np.flatnonzero(sel)[_thin(int(sel.sum()))]
    colors = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]
    naive = result.naive_mm
    w = max(1, round(1.0 / result.session.dt))
    naive_avg = pd.Series(naive).rolling(w, min_periods=1, center=True).mean().to_numpy()
    ax.plot(t[idx], naive_avg[idx], color="0.6", lw=0.8, label="naive ω_r R_r/ω_w (1 s mean)")
    label_out = "smoothed" if result.options.smoother else "filter"
    for run, c in zip(result.runs, colors * 4, strict=False):
        lo = run.radius_mm - 2 * run.radius_std_mm
        hi = run.radius_mm + 2 * run.radius_std_mm
        ax.fill_between(t[idx], lo[idx], hi[idx], color=c, alpha=0.2, lw=0)
        if result.options.smoother:
            ax.plot(t[idx], run.filter_mm[idx], color=c, lw=0.6, alpha=0.6, ls="--",
                    label=f"r0 = {run.r0_mm:g} mm, filter")  # fmt: skip
        ax.plot(t[idx], run.radius_mm[idx], color=c, lw=1.4,
                label=f"r0 = {run.r0_mm:g} mm, {label_out} ± 2σ")  # fmt: skip
    if result.reference_mm is not None:
        ax.axhline(result.reference_mm, color="k", lw=1.0, ls=":", label="reference")
    centre = result.runs[0].radius_mm[-1]
    span = 8.0 if window is None else 60.0
    ax.set_ylim(centre - span, centre + span)
    ax.set_xlabel("time, s")
    ax.set_ylabel("rolling radius, mm")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right", ncol=2)
    return fig


def _time_panels(result: RollerRigResult) -> tuple[Figure, tuple[Axes, Axes], np.ndarray]:
    """Two panels over the run's time (shared axis), and the samples they plot (thinned)."""
    fig = Figure(figsize=(9.0, 5.0), dpi=110)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    return fig, (ax1, ax2), np.arange(result.time.size)[_thin(result.time.size)]


def speeds_figure(result: RollerRigResult) -> Figure:
    """Measured and estimated wheel and roller speeds, torque request."""
    fig, (ax1, ax2), idx = _time_panels(result)
    t = result.time
    st = result.runs[0].states
    ax1.plot(t[idx], result.omega_w[idx], color="0.7", lw=0.5, label="ω_w measured")
    ax1.plot(t[idx], st[idx, 0], color="tab:blue", lw=1.0, label="ω_w estimated")
    ax1.plot(t[idx], result.omega_r[idx], color="0.5", lw=0.5, label="ω_r measured")
    ax1.plot(t[idx], st[idx, 1], color="tab:red", lw=1.0, label="ω_r estimated")
    ax1.set_ylabel("rad/s")
    ax1.legend(fontsize=7, ncol=2)
    ax1.grid(alpha=0.3)
    ax2.plot(t[idx], result.torque[idx], color="tab:green", lw=1.0)
    ax2.set_ylabel("torque request, N m")
    ax2.set_xlabel("time, s")
    ax2.grid(alpha=0.3)
    return fig


def creep_figure(result: RollerRigResult) -> Figure:
    """Creep force (estimated states) and the roller transducer, creepage."""
    fig, (ax1, ax2), idx = _time_panels(result)
    t = result.time
    w = max(1, round(0.5 / result.session.dt))

    def mean(x: np.ndarray) -> np.ndarray:
        return pd.Series(x).rolling(w, min_periods=1, center=True).mean().to_numpy()

    ax1.plot(t[idx], result.creep_force[idx], color="tab:purple", lw=0.4, alpha=0.35)
    ax1.plot(t[idx], mean(result.creep_force)[idx], color="tab:purple", lw=1.4,
             label="model at the estimated states (0.5 s mean)")  # fmt: skip
    if result.session.has("roller_torque"):
        shaft = result.session.values("roller_torque") / result.spec.roller_radius
        ax1.plot(t[idx], mean(shaft)[idx], color="k", lw=1.0, ls="--",
                 label="roller transducer / R_r (0.5 s mean)")  # fmt: skip
    ax1.set_ylabel("creep force, N")
    ax1.legend(fontsize=7)
    ax1.grid(alpha=0.3)
    ax2.plot(t[idx], result.creepage[idx] * 100.0, color="tab:brown", lw=0.4, alpha=0.35)
    ax2.plot(t[idx], mean(result.creepage)[idx] * 100.0, color="tab:brown", lw=1.4)
    ax2.set_ylabel("creepage, %")
    ax2.set_xlabel("time, s")
    ax2.grid(alpha=0.3)
    return fig


CREEP_NAMES = {"polach": "Polach law", "fastsim": "FASTSIM table (Kalker)"}


def _method_text(result: RollerRigResult) -> list[str]:
    """The page's paragraphs on the filter, the supply, restarts, consistency, the law."""
    s = result.summary
    text = [
        f"Joint UKF on [ω_w, ω_r, r_w] (paper eq. 10-14), α = {s['filter']['alpha']:g}, "
        f"β = {s['filter']['beta']:g}, κ = {s['filter']['kappa']:g}, RK4 at "
        f"{s['filter']['rk4_substep_s'] * 1e3:g} ms inside each {result.session.dt * 1e3:g} ms "
        f"sample; creep law {s['filter']['creep_law']}; tuning '{s['filter']['tuning']}'; "
        + ("unscented RTS smoother on." if result.options.smoother else "filter only (the paper)."),
        f"Roller motor supply {result.supply_hz:.3f} Hz ({result.supply_source}).",
    ]  # fmt: skip
    text.extend(f"From r0 = {r['r0_mm']:g} mm: {r['restarted']}." for r in s["runs"]
                if r["restarted"])
    text.append("Filter consistency (speeds), first guess: "
                + consistency_text(s["runs"][0]["consistency"]) + ".")
    if s["filter"]["with_effect"] is not None:
        text.append("The creep law carries " + carried_text(s["filter"]["with_effect"]) + ".")
    return text


def roller_rig_page(result: RollerRigResult) -> Page:
    """The report page of one roller-rig run (``result``: RollerRigResult)."""
    s = result.summary
    ref = result.reference_mm
    first = s["runs"][0]
    conv = [r["convergence_time_s"] for r in s["runs"] if not r["restarted"]]
    conv_ok = [c for c in conv if c is not None]
    cards = [
        Card("rolling radius", f"{first['radius_mm']:.2f}", "mm"),
        Card("1-sigma", f"{first['radius_std_mm']:.3f}", "mm"),
        Card("reference", number_text(ref, ".2f"), "mm" if ref is not None else ""),
        Card("converged within 1 mm", number_text(max(conv_ok) if conv_ok else None, ".2f"), "s"),
    ]
    table1 = _table1(result)
    cmp_table = _naive_table(s["naive_vs_ukf"])
    text = _method_text(result)
    naive_text = _naive_text(s["naive_vs_ukf"], ref)
    t_end = min(float(result.time[-1]), 0.3)
    sections = [
        Section("Rolling radius", text, [table1],
                {"radius": radius_figure(result),
                 "radius_start": radius_figure(result, (float(result.time[0]), t_end))},
                ["Bands: ±2σ of each run's posterior, widened by the creep law's error "
                 f"the session shows ({result.runs[0].model_error_mm_per_knm:.3f} mm per kN m"
                 " of traction torque: how far the estimate leaves its free-rolling value "
                 "under load, which a constant radius cannot do), and by its departure from"
                 " the free-rolling speed ratio "
                 f"(±{result.runs[0].ratio_error_mm:.3f} mm, 1σ). Dashed: the forward filter"
                 " (the paper's estimate); solid: the output track."]),
        Section("Naive speed-ratio radius vs the UKF", [naive_text], [cmp_table]),
        Section("Speeds and torque", [], [], {"speeds": speeds_figure(result)}),
        Section("Creep", [], [], {"creep": creep_figure(result)},
                [f"Creep force from the estimator's {CREEP_NAMES[s['filter']['creep_law']]} at"
                 " the estimated states; the "
                 "roller transducer is shown for validation only (the filter never reads it)."]),
    ]  # fmt: skip
    return Page(
        title=f"Roller rig — {result.stem}",
        subtitle=f"{s['duration_s']:.0f} s at {s['rate_hz']:.0f} Hz, rig '{s['rig']}'",
        cards=cards,
        sections=sections,
        footer="brakethermo roller-rig (Onat, Voltr, Lata: UKF rolling-radius estimation)",
    )


def _table1(result: RollerRigResult) -> TableBlock:
    """Each guess's whole-run RMSE and convergence beside the paper's Table 1."""
    s = result.summary
    ref = result.reference_mm
    speed = paper_speed_kmh(result.supply_hz)
    paper = PAPER_TABLE1[speed]
    rows = []
    for r in s["runs"]:
        kind = "–" if ref is None else ("under" if r["r0_mm"] < ref else "over")
        paper_mm = None if ref is None else paper[0 if r["r0_mm"] < ref else 1]
        rows.append([
            f"{r['r0_mm']:g}", kind,
            number_text(r["filter_rmse_vs_ref_mm"], ".3f") + (
                "" if ref is None else f" ({r['filter_rmse_vs_ref_pct']:.3f} %)"),
            number_text(r["rmse_vs_ref_mm"], ".3f") + (
                "" if ref is None else f" ({r['rmse_vs_ref_pct']:.3f} %)"),
            number_text(paper_mm, ".4f")
            + ("" if paper_mm is None else f" ({100 * paper_mm / PAPER_RADIUS_MM:.2f} %)"),
            "restarted" if r["restarted"] else number_text(r["convergence_time_s"], ".2f"),
            number_text(r["max_error_after_convergence_mm"], ".3f"),
        ])  # fmt: skip
    out_name = "smoothed" if result.options.smoother else "filter"
    return TableBlock(
        ["r0, mm", "case", "filter RMSE, mm", f"{out_name} RMSE, mm",
         f"paper Table 1, {speed} km/h", "convergence, s", "max |error| after, mm"],
        rows,
        caption="Whole-run RMSE of the radius against the session's reference, the "
        "convergence from the guess included (paper eq. 16); the paper's figure is for "
        f"its {speed} km/h scenario on the real rig.",
    )  # fmt: skip


def _naive_table(cmp: dict[str, Any]) -> TableBlock:
    """The naive speed-ratio radius and the UKF's by phase, mm (``cmp``: the summary's
    ``naive_vs_ukf``)."""
    cmp_rows = [
        ["free rolling", number_text(cmp["naive_free_mm"], ".3f"),
         number_text(cmp.get("naive_free_error_mm"), "+.3f"), "", ""],
        ["traction", number_text(cmp["naive_traction_mm"], ".3f"),
         number_text(cmp.get("naive_traction_error_mm"), "+.3f"),
         number_text(cmp["ukf_traction_mm"], ".3f"),
         number_text(cmp.get("ukf_traction_error_mm"), "+.3f")],
    ]  # fmt: skip
    return TableBlock(
        ["phase", "naive, mm", "naive − ref, mm", "UKF, mm", "UKF − ref, mm"], cmp_rows,
        caption="Phase means; free rolling: torque request below 2 % of its peak, "
        "traction: above 50 %.")


def _naive_text(cmp: dict[str, Any], ref: float | None) -> str:
    """Why the naive radius reads low under traction, and by how much here.

    Parameters
    ----------
    cmp : dict
        The summary's ``naive_vs_ukf``, mm.
    ref : float or None — mm
        The session's reference radius.
    """
    drop = cmp["naive_traction_drop_mm"]
    naive_text = (
        "The naive radius ω_r·R_r/ω_w ignores creep: right in free rolling, it reads low "
        "under traction because the wheel surface runs faster than the roller's."
    )
    if drop is not None:
        naive_text += f" Here it drops by {drop:.3f} mm from free rolling to traction."
    if ref is not None and cmp.get("naive_traction_error_mm") is not None:
        n_err, u_err = abs(cmp["naive_traction_error_mm"]), abs(cmp["ukf_traction_error_mm"])
        if u_err < n_err:
            than = f"{n_err / u_err:.1f}x smaller error" if u_err > 0 else "no error"
        elif u_err > n_err:
            # the filter's creep (law, roller motor) is further off than the creep it adds
            than = (f"{u_err / n_err:.1f}x larger error: the filter's creep law or roller"
                    " motor departs from this rig's; see diagnose" if n_err > 0 else
                    "the naive ratio is exact here")
        else:
            than = "the same error"
        naive_text += (
            f" Under traction the naive ratio is {n_err:.3f} mm off the reference, the UKF "
            f"{u_err:.3f} mm ({than})."
        )
    return naive_text
