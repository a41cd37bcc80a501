"""Report page of `brakethermo ebooster`: Table 1 of paper 004, pressures, bands, residuals."""

from __future__ import annotations

import math
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from brakethermo.numeric import rmse
from brakethermo.report.page import (
    Card,
    Page,
    Section,
    TableBlock,
    as_number,
    finish_figure,
    number_text,
)
from brakethermo.results.ebooster import (
    OBSERVERS,
    PRESSURES,
    EboosterResult,
    static_pressure,
)
from brakethermo.results.rig_diagnosis import carried_text

COLOURS = {"ukf": "#1f77b4", "ekf": "#d62728"}
MAX_POINTS = 4000  # plotted points per curve; the data keep every sample
PAPER_TABLE1 = (("open loop", 0.2758, 0.2406, 12.75), ("closed loop", 0.2405, 0.1999, 16.87),
                ("vehicle test", 0.0565, 0.0472, 16.47))


def _every(n: int) -> slice:
    return slice(None, None, max(1, n // MAX_POINTS))


def _states_figure(r: EboosterResult) -> Figure:
    sl = _every(r.time.size)
    t = r.time[sl]
    fig, axes = plt.subplots(5, 1, figsize=(11, 12), sharex=True)
    labels = ("p_m MPa", "p_f MPa", "p_r MPa", "ζ1 = δ mm", "ζ2 mm/s")
    for i, ax in enumerate(axes):
        for w in OBSERVERS:
            tr = r.tracks[w]
            x, sd = tr.x[sl, i], tr.std[sl, i]
            ax.plot(t, x, color=COLOURS[w], lw=0.8, label=f"{w.upper()} ±2σ")
            ax.fill_between(t, x - 2 * sd, x + 2 * sd, color=COLOURS[w], alpha=0.2, lw=0)
        state = ("p_m", "p_f", "p_r")[i] if i < 3 else None
        if state in r.validation:
            ax.plot(t, r.validation[state][sl], color="k", lw=0.6, label="sensor (validation)")
        if i == 3:
            ax.plot(t, r.delta[sl], color="k", lw=0.4, alpha=0.6, label="δ measured")
        ax.set_ylabel(labels[i])
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time s")
    fig.tight_layout()
    return fig


def _residual_figure(r: EboosterResult) -> Figure:
    sl = _every(r.time.size)
    fig, (ax, hx) = plt.subplots(1, 2, figsize=(11, 3.6), gridspec_kw={"width_ratios": [3, 1]})
    for w in OBSERVERS:
        res = r.tracks[w].residual
        ax.plot(r.time[sl], res[sl], color=COLOURS[w], lw=0.6, alpha=0.8, label=w.upper())
        finite = res[np.isfinite(res)]
        hx.hist(finite, bins=60, color=COLOURS[w], alpha=0.5, label=w.upper(), density=True)
    hx.set_xlabel("δ residual mm")
    return finish_figure(fig, ax, "time s", "δ residual mm")


def _pv_figure(r: EboosterResult) -> Figure:
    fig, ax = plt.subplots(figsize=(6, 4))
    s = np.linspace(0.0, max(float(np.max(r.s2)), 1.0), 200)
    name = "p–V fit, knots" if r.fit.pv_knots_mm else "RLS p–V fit"
    ax.plot(s, r.fit.pressure(s), color="k", label=f"{name} (tangent beyond the training"
            " travel)" if s[-1] > r.fit.s2_max_mm else name)
    if "p_m" in r.validation:
        sl = _every(r.time.size)
        ax.plot(r.s2[sl], r.validation["p_m"][sl], ".", ms=1.5, alpha=0.4,
                label="this session (sensor)")
    return finish_figure(fig, ax, "screw displacement s2, mm",
                         "master-cylinder pressure p_m, MPa")


def _band_words(s: dict, pv_only: float | None) -> list[str]:
    """What the pressure table shows, computed from it: whether the UKF's p_m band is as
    wide as its errors (outside 1σ against the 32 % of a consistent band), and whether the
    observers beat the p–V curve alone (None: the session has no p_m sensor)."""
    out1 = as_number(s["outside_1sigma"]["ukf"]["p_m"])
    cov = as_number(s["coverage_95"]["ukf"])
    words = []
    if math.isfinite(out1) and math.isfinite(cov):
        # conservative only where the 95 % band holds too: a 1σ share under 20 % beside a
        # 95 % coverage of 93.8 % was called conservative (review)
        width = ("wider than its errors (conservative)" if out1 < 0.2 and cov >= 0.95 else
                 "narrower than its errors" if out1 > 0.45 or cov < 0.85 else
                 "about as wide as its errors")
        words.append(f"Here the UKF's p_m band leaves {100 * out1:.1f} % outside 1σ (32 % for"
                     f" a band as wide as its errors), and its pressure bands (p_m, p_f and"
                     f" p_r together) cover {100 * cov:.1f} % at 95 %: the p_m band is"
                     f" {width}.")
    observers = {w: as_number(s["pressure_rmse_mpa"][w]["p_m"]) for w in ("ukf", "ekf")}
    if pv_only is not None and all(math.isfinite(v) and pv_only <= v
                                   for v in observers.values()):
        words.append(f"The p–V curve alone ({pv_only:.3f} MPa RMSE) does as well as or"
                     f" better than both observers here (UKF {observers['ukf']:.3f}, EKF"
                     f" {observers['ekf']:.3f} MPa): on this session their dynamics add"
                     " nothing to the master-cylinder pressure.")
    return words


def _pressure_table(s: dict[str, Any]) -> TableBlock:
    """The observers' pressures against the session's sensors, from the summary ``s``."""
    rows = []
    for w in OBSERVERS:
        pr, out1 = s["pressure_rmse_mpa"][w], s["outside_1sigma"][w]
        rows.append((w.upper(), *(number_text(pr[k], ".3f") for k in PRESSURES),
                     *(number_text(100 * as_number(out1[k]), ".1f") for k in PRESSURES),
                     *(number_text(100 * as_number(c), ".1f")
                       for c in (s["coverage_95"][w], s["coverage_95_braking"][w])),
                     f"{s['consistency'][w]['mean_nis']:.2f} ({s['consistency'][w]['state']})"))
    return TableBlock(
        header=("observer", "p_m RMSE MPa", "p_f RMSE MPa", "p_r RMSE MPa", "p_m outside 1σ %",
                "p_f outside 1σ %", "p_r outside 1σ %", "95 % band coverage %",
                "… while braking %", "δ mean NIS"),
        rows=rows,
        caption="Against the session's pressure channels (validation only; – where the "
        "session has none). A consistent 1σ band leaves about 32 % outside, a 95 % band 5 %."
        " δ mean NIS: the filter's normalised innovations, 1 when its noise settings match"
        f" ({s['consistency']['ukf']['chi2_band'][0]:.2f}–"
        f"{s['consistency']['ukf']['chi2_band'][1]:.2f} for this session's length).",
    )


def booster_page(r: EboosterResult) -> Page:
    """The report page of one run."""
    s = r.summary
    res = s["residual_rmse_mm"]
    cards = [
        Card("δ residual RMSE UKF", number_text(res["ukf"], ".4f"), "mm"),
        Card("δ residual RMSE EKF", number_text(res["ekf"], ".4f"), "mm"),
        Card("UKF improvement over EKF (residual RMSE)", number_text(s["improvement_pct"], ".1f"),
             "%"),
    ]
    if (p_m := s["pressure_rmse_mpa"]["ukf"]["p_m"]) is not None:
        cards.append(Card("p_m RMSE UKF", number_text(p_m, ".3f"), "MPa"))
    table1 = TableBlock(
        header=("case", "EKF residual RMSE mm", "UKF residual RMSE mm", "improvement %"),
        rows=[("this session", number_text(res["ekf"], ".4f"), number_text(res["ukf"], ".4f"),
               number_text(s["improvement_pct"], ".2f"))]
        + [(f"paper: {c}", f"{e:.4f}", f"{u:.4f}", f"{i:.2f}") for c, e, u, i in PAPER_TABLE1],
        caption="Table 1 of the paper for this session (residual = measured minus one-step "
        "predicted δ); the paper's rows for reference.",
    )
    ptable = _pressure_table(s)
    pv_only = None
    if "p_m" in r.validation:
        err = static_pressure(r) - r.validation["p_m"]
        pv_only = rmse(err)
    notes = [
        f"p–V fit from {s['pv_fit']['training_session']}: {s['pv_fit']['curve']}; "
        f"training RMSE {s['pv_fit']['rmse_mpa']:.4f} MPa"
        + (f"; the p–V curve alone on this session: {pv_only:.3f} MPa RMSE" if pv_only else ""),
        "The EKF linearises the chi-square pedal force F = F_scale w² at the mean of w; the "
        "UKF's sigma points keep its curvature. Near w = 0 (no pedal force) neither filter "
        "can tell the sign of w, and the UKF's wide Gaussian over w turns into a positive "
        "force bias: the paper's advantage is not guaranteed on every session.",
    ]
    if s["with_effect"] is not None:
        notes.insert(1, "Both observers' p–V carries " + carried_text(s["with_effect"]) + ".")
    said = _band_words(s, pv_only)
    choice = s.get("noise_choice")
    band_notes = notes[:1] + ([f"Process noise of the physical states: {choice['q_factor']:g}x"
                               f" the datasheet's — {choice['why']}."] if choice else [])
    smooth = "smoothed (RTS)" if s["smoothed"] else "filtered"
    return Page(
        title=f"E-Booster observation — {r.session.path.name}",
        subtitle=f"UKF vs EKF on the same model and noise, {s['samples']} samples at "
        f"{s['rate_hz']:.0f} Hz; states {smooth}",
        cards=cards,
        # the console prints the warnings; the page is read without it
        sections=([Section("Warnings", paragraphs=list(s["warnings"]))] if s["warnings"]
                  else []) + [
            Section("Residuals (paper Table 1)", tables=[table1],
                    figures={"residuals": _residual_figure(r)}),
            Section("Pressures and bands", paragraphs=said, tables=[ptable],
                    figures={"states": _states_figure(r)}, notes=band_notes),
            Section("Identification", figures={"pv_fit": _pv_figure(r)},
                    paragraphs=[
                        f"Disk quasi-static three-slope fit (eq. 14): breakpoints "
                        f"{r.fit.disk[0]:.0f} N, {r.fit.disk[1]:.0f} N, slopes "
                        f"{r.fit.disk[2]:.2e}, {r.fit.disk[3]:.2e}, {r.fit.disk[4]:.2e} mm/N; "
                        f"dynamics ω_n = {r.fit.omega_n:.1f} rad/s, damping "
                        f"{r.fit.damping:.2f}, zero τ = {r.fit.tau_z * 1e3:.1f} ms; "
                        f"pedal force scale {r.fit.pedal_scale_n:.1f} N per degree of freedom.",
                    ], notes=notes[1:]),
        ],
        footer="brakethermo ebooster — paper 004 (Mei et al., Actuators 2023)",
    )
