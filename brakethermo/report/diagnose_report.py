"""The diagnosis page: consistency, where the gap lies, which effect, how far it shrinks."""

from __future__ import annotations

import math
from typing import Any

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from scipy.special import chdtri  # scipy.stats costs 0.5 s of import

from brakethermo.report.page import Card, Page, Section, TableBlock, as_number
from brakethermo.report.page import number_text as num
from brakethermo.thermal.hlaw_check import B_LAW_CHECKED

SPOT_COLOURS = ("#1f77b4", "#2ca02c", "#ff7f0e", "#d62728")
DIST_BIN_M = 25.0


def residual_map(dist: np.ndarray, lap: np.ndarray, res: np.ndarray) -> Figure:
    """Mean reference residual (measured − model) by lap distance and spot, flying laps."""
    fig = Figure(figsize=(11.0, 3.4), dpi=110)
    ax = fig.add_subplot()
    flying = lap >= 1
    edges = np.arange(0.0, float(np.nanmax(dist[flying])) + DIST_BIN_M, DIST_BIN_M)
    idx = np.clip(np.digitize(dist, edges) - 1, 0, edges.size - 2)
    grid = np.full((4, edges.size - 1), np.nan)
    for i in range(4):
        ok = flying & np.isfinite(res[:, i])
        s = np.bincount(idx[ok], weights=res[ok, i], minlength=edges.size - 1)
        n = np.bincount(idx[ok], minlength=edges.size - 1)
        grid[i, n > 0] = s[n > 0] / n[n > 0]
    lim = max(float(np.nanpercentile(np.abs(grid), 98)), 1.0)
    im = ax.imshow(grid, aspect="auto", cmap="RdBu_r", norm=TwoSlopeNorm(0.0, -lim, lim),
                   extent=(edges[0], edges[-1], 4.5, 0.5), interpolation="nearest")
    ax.set_yticks([1, 2, 3, 4], ["spot 1", "spot 2", "spot 3", "spot 4"])
    ax.set_xlabel("lap distance [m]")
    ax.set_title("Reference model residual, measured − model [°C] (mean over flying laps)",
                 loc="left", fontsize=11)
    fig.colorbar(im, ax=ax, pad=0.01, label="°C")
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.17, top=0.88)
    return fig


def nis_figure(time: np.ndarray, nis: np.ndarray, window_s: float = 10.0) -> Figure:
    """Moving mean of the per-step NIS of the reference filter, with the χ² band of such a
    mean for white innovations of a consistent filter."""
    fig = Figure(figsize=(11.0, 2.8), dpi=110)
    ax = fig.add_subplot()
    dt = float(np.median(np.diff(time))) if time.size > 1 else 0.1
    n = max(round(window_s / dt), 1)
    ok = np.isfinite(nis)
    kernel = np.ones(n)
    total = np.convolve(np.where(ok, nis, 0.0), kernel, mode="same")
    count = np.convolve(ok.astype(float), kernel, mode="same")
    mean = np.where(count > n / 2, total / np.maximum(count, 1), np.nan)
    lo, hi = chdtri(n, [0.975, 0.025]) / n  # chi2.ppf([.025, .975], n)
    ax.axhspan(lo, hi, color="#2ca02c", alpha=0.18, label=f"χ² 95 % band of a {window_s:g} s mean")
    ax.axhline(1.0, color="#2ca02c", lw=0.8)
    ax.plot(time, mean, lw=1.2, color="#1d2330", label=f"NIS, {window_s:g} s moving mean")
    top = float(np.nanpercentile(mean, 99)) if np.isfinite(mean).any() else 2.0
    ax.set_ylim(0.0, max(2.0, 1.15 * top))
    ax.set_xlabel("time [s]")
    ax.set_ylabel("NIS per spot")
    ax.set_title("Filter consistency: normalised innovation squared (1 = consistent)",
                 loc="left", fontsize=11)
    ax.legend(loc="upper right", fontsize=9)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.2, top=0.86)
    return fig


def _significant_text(e: dict[str, Any]) -> str:
    """'yes'/'no', and where the effect's signature lives, its shrink there."""
    text = "yes" if e["significant"] else "no"
    if "signature_where" not in e:
        return text
    lo, hi = e["signature_shrink_ci95_pct"]
    how = "by its signature" if e.get("significant_by") == "signature" else "signature"
    point = e["signature_shrink_pct"]
    span = (f"[{num(lo, '.0f')} … {num(hi, '.0f')}]" if math.isfinite(as_number(lo))
            else "[no interval: one unit]" if math.isfinite(as_number(point))
            else "[none in the held-out laps]")
    return (f"{text} ({how}: {num(point, '+.0f')} % {span}"
            f" on {e['signature_where']})")


def effects_figure(effects: list[dict[str, Any]], verdict: str) -> Figure:
    """Held-out RMSE before and after each effect, with the shrink and its interval."""
    fig = Figure(figsize=(11.0, 3.6), dpi=110)
    ax = fig.add_subplot()
    names = [e["name"] for e in effects]
    x = np.arange(len(names))
    before = [e["rmse_before"] for e in effects]
    after = [e["rmse_after"] for e in effects]
    ax.bar(x - 0.2, before, 0.4, color="#c9cfdb", label="reference")
    colours = ["#d62728" if n == verdict else "#1f77b4" for n in names]
    ax.bar(x + 0.2, after, 0.4, color=colours, label="with the effect")
    for xi, e in zip(x, effects, strict=True):
        lo, hi = e["shrink_ci95_pct"]
        ax.annotate(f"{num(e['shrink_pct'], '+.0f')} %\n[{num(lo, '.0f')}, {num(hi, '.0f')}]",
                    (xi + 0.2, e["rmse_after"]), ha="center", va="bottom", fontsize=8)
    ax.set_xticks(x, [n.replace("_", "\n") for n in names], fontsize=9)
    ax.set_ylabel("held-out RMSE [°C]")
    ax.set_title("Which effect: held-out RMSE and shrink [95 % bootstrap interval]", loc="left",
                 fontsize=11)
    # above the axes: inside, it sat on the last bar's label
    ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=2, fontsize=9, frameon=False)
    ax.set_ylim(0, max([*before, *after, 1.0]) * 1.35)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.2, top=0.86)
    return fig


def heldout_trace(time: np.ndarray, lap: np.ndarray, y: np.ndarray, ref: np.ndarray,
                  best: np.ndarray | None, held_lap: int, label: str) -> Figure:
    """Measured spots, the reference and the best effect's model on one held-out lap."""
    fig = Figure(figsize=(11.0, 3.8), dpi=110)
    ax = fig.add_subplot()
    m = lap == held_lap
    for i in range(y.shape[1]):  # every spot (spot 1's error was the largest, and hidden)
        ax.plot(time[m], y[m, i], color=SPOT_COLOURS[i], lw=1.0, label=f"spot {i + 1} measured")
        ax.plot(time[m], ref[m, i], color=SPOT_COLOURS[i], lw=0.9, ls=":")
        if best is not None:
            ax.plot(time[m], best[m, i], color=SPOT_COLOURS[i], lw=0.9, ls="--")
    ax.plot([], [], color="k", ls=":", label="reference model")
    if best is not None:
        ax.plot([], [], color="k", ls="--", label=f"with {label}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("°C")
    ax.set_title(f"Held-out lap {held_lap}: open-loop model vs measurement", loc="left",
                 fontsize=11)
    ax.legend(loc="upper right", fontsize=8, ncol=2)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.15, top=0.88)
    return fig


def _scored_on_fewer(effects: list[dict[str, Any]]) -> list[str]:
    """Why an effect's 'before' differs from the others': it is scored on fewer spots."""
    every = max((len(e.get("scored_spots", [])) for e in effects), default=0)
    return [f"{e['name']} is scored on {', '.join(e['scored_spots'])} (the race spot placed"
            " its held-out straights), so its 'before' is the reference on those"
            for e in effects if 0 < len(e.get("scored_spots", [])) < every]


def diagnosis_page(summary: dict[str, Any], time: np.ndarray, lap: np.ndarray,
                   y: np.ndarray, ref: np.ndarray, best: np.ndarray | None,
                   dist: np.ndarray, nis: np.ndarray, title: str) -> Page:
    """The whole diagnosis page from the summary and the residual series."""
    effects = summary["effects"]
    verdict = summary["verdict"]
    vset = summary.get("verdict_set", [] if verdict == "none" else [verdict])
    top = next((e for e in effects if e["name"] == verdict), None)
    cons = summary["consistency"]
    shown = (" or ".join(v.replace("_", " ") for v in vset) if len(vset) > 1 else
             verdict.replace("_", " "))
    cards = [
        Card("Gap (held-out RMSE)", num(summary["gap"]["rmse_c"]), "°C"),
        Card("Verdict" if len(vset) < 2 else "Verdict: cannot tell apart", shown),
        Card("Shrink", num(top["shrink_pct"], '.0f') if top else "–", "%" if top else ""),
        Card("Held-out laps", ", ".join(map(str, summary["heldout_laps"]))),
    ]
    ref_section = _reference_section(summary)
    cons_section = _consistency_section(cons, time, nis)
    where_section = _where_section(summary, dist, lap, y - ref)
    which_section = _which_section(summary, vset, shown)
    next_section = Section("What to run or measure next",
                           list(summary.get("next_steps", [])) or
                           ["Nothing to carry: the reference model explains the held-out laps"
                            " within the rule."])
    held = summary["heldout_laps"][0]
    trace_section = Section(
        "A held-out lap",
        [],
        figures={"heldout_lap": heldout_trace(time, lap, y, ref, best, held,
                                              effects[0]["name"] if effects else "")},
    )
    return Page(
        title=f"{title} · diagnosis",
        subtitle=f"disc {summary['run']['disc']}, brakethermo {summary['run']['brakethermo']}",
        cards=cards,
        sections=[ref_section, cons_section, where_section, which_section, next_section,
                  trace_section],
        footer="Effects are fitted on the training laps only; 'after' figures are held-out.",
        back_href="../index.html",
    )


def _slow_text(summary: dict[str, Any]) -> str:
    """The slow laps among those used, said as such (" Lap 7 took 1.43 x ...")."""
    slow = summary.get("slow_laps") or {}
    if not slow:
        return ""
    laps = ", ".join(slow)
    shares = ", ".join(f"{share:.2f}" for share in slow.values())
    if len(slow) > 1:
        return (f" Laps {laps} took {shares} x the typical lap time: in-laps or cool-down"
                " laps, used as any other (their cooling is data for the model) but no"
                " flying laps.")
    return (f" Lap {laps} took {shares} x the typical lap time: an in-lap or a cool-down"
            " lap, used as any other (its cooling is data for the model) but no flying lap.")


def _reference_section(summary: dict[str, Any]) -> Section:
    """What the reference model contains, what it was fitted on, and its fitted values."""
    ref = summary["reference"]
    return Section(
        "The reference model",
        [_fitted_on_text(summary) + _slow_text(summary)],
        [TableBlock(["contains"], [[c] for c in ref["contains"]])],
        notes=_reference_notes(ref),
    )


def _fitted_on_text(summary: dict[str, Any]) -> str:
    """Which laps the reference was fitted on and which the 'after' figures score; a
    single-spot race fits nothing offline (its reference is the race estimator, scored
    by one-step innovations), and the page said "Fitted on laps ;" there."""
    held = ", ".join(map(str, summary["heldout_laps"]))
    if not summary["train_laps"]:
        return (f"Nothing is fitted offline: the reference runs the race estimator with the"
                f" given h law, and every figure below scores its one-step-ahead predictions"
                f" (from past readings only) on laps {held or 'none'}.")
    return (f"Fitted on laps {', '.join(map(str, summary['train_laps']))}; every 'after'"
            f" figure below is measured on laps {held}, which no fit saw (the out-lap is"
            " used by neither).")


def _reference_notes(ref: dict[str, Any]) -> list[str]:
    """The reference's fitted values (none: nothing said) and what makes them suspect: an
    h law flat with speed, a parameter at a bound of its range (found: "Fitted: h_a = 104,
    h_b = 2.8e-06" with nothing said)."""
    notes = []
    if ref.get("fitted"):
        notes.append("Fitted: " + ", ".join(
            f"{k} = {num(v, '.3g') if not isinstance(v, list) else [round(x, 3) for x in v]}"
            for k, v in ref["fitted"].items()))
    if ref.get("law_check"):
        notes.append("WARNING: " + ref["law_check"]["text"])
    shown = {k: v for k, v in (ref.get("at_bounds") or {}).items()
             if k != "reference.b" or v > B_LAW_CHECKED}
    if shown:
        notes.append("WARNING: at a bound of its range: " + ", ".join(
            f"{k} = {num(v, '.3g')}" for k, v in shown.items())
            + " (the data push it past the reference's range: read the 'before' figures"
            " with care)")
    return notes


def _consistency_section(cons: dict[str, Any], time: np.ndarray, nis: np.ndarray) -> Section:
    """The reference filter's consistency per spot, with the NIS trace.

    Parameters
    ----------
    cons : dict
        The summary's ``consistency``.
    time : ndarray — s
    nis : ndarray
        Per-step NIS of the reference filter.
    """
    return Section(
        "Consistency first",
        [cons["summary"]],
        [TableBlock(["spot", "mean NIS", "χ² band", "lag-1 autocorrelation", "state"],
                    [[k, num(v["mean_nis"], '.2f'),
                      f"{num(v['chi2_band'][0], '.2f')}–{num(v['chi2_band'][1], '.2f')}",
                      num(v["lag1_autocorrelation"], '.2f'), v["state"]]
                     for k, v in cons["per_spot"].items()])],
        {"nis": nis_figure(time, nis)},
    )


def _where_section(summary: dict[str, Any], dist: np.ndarray, lap: np.ndarray,
                   res: np.ndarray) -> Section:
    """Where the reference model parts from the disc: per spot and phase, ranked cells, and
    the residual map.

    Parameters
    ----------
    summary : dict
        The diagnosis summary.
    dist : ndarray — m
        Lap distance.
    lap : ndarray of int
    res : ndarray (n, 4) — degC
        Reference residual, measured − model.
    """
    gap = summary["gap"]["per_spot_phase"]
    where_rows = [[c["spot"], c["phase"], c["zone"] or "–",
                   c["speed_band_kmh"], c["temp_band_c"], num(c["rmse_c"]), num(c["bias_c"]),
                   num(c["share_pct"])] for c in summary["where"]["ranked_cells"]]
    return Section(
        "Where the model parts from the disc",
        ["Held-out RMSE of the reference model per spot and phase (°C):"],
        [TableBlock(["spot", "braking", "cooling"],
                    [[k, num(v["braking"]), num(v["cooling"])] for k, v in gap.items()]),
         TableBlock(["spot", "phase", "zone", "speed km/h", "temperature °C", "RMSE °C",
                     "bias °C", "share of squared error %"], where_rows,
                    caption="Cells ranked by their share of the squared error (all flying"
                            " laps, the training laps and the held-out ones; bias ="
                            " measured − model)")],
        {"residual_map": residual_map(dist, lap, res)},
    )


def _why(summary: dict[str, Any]) -> str:
    """The clause that made the verdict a set, in brackets ("" for a single name)."""
    why = summary.get("verdict_why", "")
    return f" ({why})" if why else ""


def _which_section(summary: dict[str, Any], vset: list[str], shown: str) -> Section:
    """Which effect, how far each shrinks the gap, their sizes, and what one spot cannot
    tell apart.

    Parameters
    ----------
    summary : dict
        The diagnosis summary.
    vset : list of str
        The effects of the verdict.
    shown : str
        The verdict in words.
    """
    effects = summary["effects"]
    which_rows = [[e["rank"], e["name"], num(e["rmse_before"]), num(e["rmse_after"]),
                   num(e["shrink_pct"], '+.1f'),
                   f"{num(e['shrink_ci95_pct'][0])} … {num(e['shrink_ci95_pct'][1])}",
                   num(e["heldout_loglik_gain"], '+.3f'), _significant_text(e),
                   e["evidence"]] for e in effects]
    combined = summary["combined"]
    sizes = [[e["name"], e.get("size_text", "")] for e in effects if e["name"] in vset]
    which_section = Section(
        "Which effect, and how far the gap shrinks",
        [f"Verdict: {shown}{_why(summary)}. Rule: {summary['verdict_rule']}.",
         *summary.get("verdict_reasons", []),
         "Combined model by forward selection: "
         + (" + ".join(combined["effects"]) if combined["effects"] else "none") + "."],
        [TableBlock(["rank", "effect", "before °C", "after °C", "shrink %", "95 % interval %",
                     "Δ log-lik", "significant", "evidence (reference residuals)"],
                    which_rows)],
        {"effects": effects_figure(effects, summary["verdict"])} if effects else {},
        [*_scored_on_fewer(effects), *summary.get("warnings", [])],
    )
    if sizes and any(text for _, text in sizes):
        which_section.tables.insert(0, TableBlock(["effect", "size (fitted on training laps)"],
                                                  sizes, caption="How big it is"))
    blind = summary.get("not_identifiable_from_one_spot")
    if blind:
        which_section.tables.append(TableBlock(
            ["effect", "why it is not diagnosed here"], [[e["name"], e["reason"]] for e in blind],
            caption="A single race pyrometer cannot tell these apart"))
        which_section.paragraphs.insert(0, summary["mode"] + ".")
    return which_section
