"""The ``clamp-force`` page: each estimator's RMSE and what it says, two seconds of traces,
the adaptive filter's stiffness factor, and the re-trained models beside the trained ones."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from brakethermo.report.page import Card, Page, Section, TableBlock
from brakethermo.results.clamp_force import (
    ESTIMATORS,
    KF_NAMES,
    PEAK_HOLD_S,
    SOURCE_NAMES,
    ClampForceResult,
    estimator_series,
    scored_force,
)


def _fmt(v: float | None) -> str:
    return "–" if v is None else f"{v:.3f}"


def _cards(res: ClampForceResult, summ: dict[str, Any]) -> list[Card]:
    """The page's headline tiles: RMSEs where the session has the sensor, else forces."""
    r, e = summ["rmse_kn"], summ["estimate_kn"]
    kf = "KF" if res.reported.kf_source == "kf" else "reported"
    if res.data.force is not None:
        return [
            Card(f"{kf} RMSE", _fmt(r["kf"]), "kN"),
            Card("ML fusion RMSE", _fmt(r["ml_fusion"]), "kN"),
            Card("adaptive KF RMSE", _fmt(summ["rmse_kn_adaptive"]), "kN"),
            Card("stiffness factor at the end (last sample)",
             f"{summ['stiffness_factor_final']:.3f}"),
        ]
    return [
        Card(f"{kf} peak force", f"{e['kf']['peak']:.2f}", "kN"),
        Card(f"{kf} 95 % band", f"± {e['kf_band95_median']:.2f}", "kN"),
        Card("mean force applied", _fmt(e["kf"]["mean_applied"]), "kN"),
        Card("stiffness factor at the end (last sample)",
             f"{summ['stiffness_factor_final']:.3f}"),
    ]


def page(res: ClampForceResult, summ: dict[str, Any]) -> Page:
    """The report page: RMSE table, traces, stiffness factor, wear."""
    force = scored_force(res)
    main = _estimators_section(res, summ, force)
    main.figures["traces"] = _traces_figure(res, force)
    sections = [main, _adaptive_section(res)]
    if "wear" in summ:
        sections.append(_wear_section(summ, force is not None))
    return Page(
        title=f"clamp-force — {res.data.session.path.name}",
        subtitle="EMB clamp force from resolver and motor current",
        cards=_cards(res, summ),
        sections=sections,
    )


def _estimators_section(res: ClampForceResult, summ: dict[str, Any],
                        force: np.ndarray | None) -> Section:
    """Each estimator's RMSE (where the session has the sensor, ``force`` N), the paper's,
    and what it says, with the sessions and the reported estimate in words."""
    r = summ["rmse_kn"]
    e = summ["estimate_kn"]
    names = ("kf", "kf_paper", "ml_fusion", "stiffness", "torque_balance", "kf_adaptive")
    est = res.reported
    reported = (f"reported: {KF_NAMES[est.kf_filter]}" if est.kf_source == "kf" else
                f"reported: the {SOURCE_NAMES[est.kf_source]}")
    labels = (reported, "the paper's KF (eq. 9-13)", "ML fusion (eq. 8)",
              "dynamic stiffness (eq. 6)", "torque balance (eq. 7)",
              "adaptive KF (stiffness factor)")
    same = est.kf_source == "kf" and est.kf_filter == "fixed"
    paper = ("0.29" if same else "–", "0.29", "0.32", "0.35", "0.61", "–")
    rmse_of = {**r, "kf_paper": summ["rmse_kn_kf_paper"],
               "kf_adaptive": summ["rmse_kn_adaptive"]}
    rows = [[lab, _fmt(rmse_of[n]), p, f"{e[n]['peak']:.2f}", _fmt(e[n]["mean_applied"])]
            for n, lab, p in zip(names, labels, paper, strict=True)]
    return Section(
        "Clamp-force estimators",
        paragraphs=[
            f"Trained on {res.train.session.path.name} ({res.train.session.time[-1]:.0f} s at"
            f" {res.train.session.rate_hz:.0f} Hz); estimated on {res.data.session.path.name}."
            + ("" if force is not None else " The session has no clamp-force sensor: each"
               " estimator's peak and mean applied force, no RMSE."),
            f"Reported estimate (kf): {summ['kf_noise']}.",
            *([summ["sensor_lag"]["text"]] if summ["sensor_lag"]["text"] else []),
        ],
        tables=[
            TableBlock(
                ["estimator", "RMSE here (kN)", "paper RMSE (kN)", "peak (kN)",
                 "mean applied (kN)"],
                rows,
                caption="RMSE against the clamp-force sensor (where the session has it; its"
                        " lag taken out where it shows one),"
                        " and what each estimator says (peak: the largest force held"
                        f" {PEAK_HOLD_S * 1e3:.0f} ms, a current step's spike dropped)",
            )
        ],
    )


def _traces_figure(res: ClampForceResult, force: np.ndarray | None) -> Figure:
    """Two seconds of every estimator's force against the sensor (``force`` N, de-lagged),
    kN."""
    t = res.data.session.time
    fig, ax = plt.subplots(figsize=(10, 3.6))
    # 2 s after the filters settled (or the whole of a short session)
    t0 = t[0] + 1.0 if t[-1] - t[0] > 3.0 else t[0]
    win = (t >= t0) & (t <= t0 + 2.0)
    if force is not None:
        lag = res.scored_lag.lag_s if res.scored_lag is not None else 0.0
        ax.plot(t[win], force[win] / 1e3, "k", lw=1.6,
                label=f"sensor, {lag * 1e3:g} ms lag out" if lag > 0.0 else "sensor")
    for name, v in estimator_series(res.reported).items():
        ax.plot(t[win], v[win] / 1e3, lw=0.8, label=name)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("clamp force (kN)")
    ax.legend(ncol=6, fontsize=8)
    fig.tight_layout()
    return fig


def _adaptive_section(res: ClampForceResult) -> Section:
    """The adaptive filter's stiffness factor with its 1σ band, and why it is there."""
    t = res.data.session.time
    fig2, ax2 = plt.subplots(figsize=(10, 2.8))
    sf, sd = res.reported.stiffness_factor, res.reported.stiffness_factor_std
    ax2.fill_between(t, sf - sd, sf + sd, alpha=0.3)
    ax2.plot(t, sf)
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("stiffness factor (–)")
    fig2.tight_layout()
    return Section(
        "Pad heating: adaptive filter",
        paragraphs=[
            "The paper held the pad temperature constant. Pads soften as they heat; the adaptive"
            " filter carries a random-walk factor on the stiffness model's input, observed"
            " through the torque balance, which the pads do not affect. A factor drifting away"
            " from 1 shows the pads changed since training."
        ],
        figures={"stiffness_factor": fig2},
    )


def _wear_section(summ: dict[str, Any], has_sensor: bool) -> Section:
    """The re-trained models beside the training session's: RMSE with the sensor, else
    peak force."""
    w = summ["wear"]
    if has_sensor:
        head = ["estimator", "RMSE not re-trained (kN)", "RMSE re-trained (kN)"]
        rows = [[k, _fmt(w["rmse_kn_not_retrained"][k]), _fmt(w["rmse_kn_retrained"][k])]
                for k in ESTIMATORS]
    else:
        e = summ["estimate_kn"]
        before = w["estimate_kn_not_retrained"]
        head = ["estimator", "peak not re-trained (kN)", "peak re-trained (kN)"]
        rows = [[k, f"{before[k]['peak']:.2f}", f"{e[k]['peak']:.2f}"] for k in ESTIMATORS]
    return Section(
        "Wear: re-training",
        paragraphs=[
            f"Re-trained on {Path(w['retraining_session']).name}"
            f" ({w['retraining_duration_s']:.0f} s with the sensor): every figure above"
            " is the re-trained models' estimate; here beside the training session's"
            " models' (`<column>_not_retrained` in the table)."
        ],
        tables=[TableBlock(head, rows)],
    )
