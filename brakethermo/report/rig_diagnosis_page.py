"""The rig diagnosis page: the reference relation against this session, and the verdict."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
from matplotlib.figure import Figure

from brakethermo.io.units import unit_suffix
from brakethermo.report.page import (
    Card,
    Page,
    Section,
    TableBlock,
    as_number,
    finish_figure,
    verdict_text,
)

RIG_NAMES = {"ebooster": "E-Booster", "emb": "EMB caliper", "roller-rig": "Roller rig",
             "tyre": "Tyre rig"}

if TYPE_CHECKING:
    from brakethermo.results.rig_diagnosis import RigDiagnosis


def _interval(lo: object, hi: object) -> str:
    """A shrink interval for the table; a dash where none was drawn (too few units)."""
    a, b = as_number(lo), as_number(hi)
    return f"{a:+.0f} … {b:+.0f}" if math.isfinite(a) and math.isfinite(b) else "– (too few units)"


def _pv_figure(r: RigDiagnosis) -> Figure:
    fig, ax = plt.subplots(figsize=(7, 4.2))
    step = max(1, r.x.size // 4000)
    s = r.summary
    ax.plot(r.x[::step], r.measured[::step], ".", ms=1.5, color="#1f77b4", alpha=0.5,
            label="this session (sensor)")
    ax.plot(r.x[::step], r.reference[::step], ".", ms=1.2, color="k", alpha=0.6,
            label="reference relation")
    if r.best is not None:
        ax.plot(r.x[::step], r.best[::step], ".", ms=1.2, color="#d62728", alpha=0.5,
                label=f"with {r.summary['verdict']} (fitted on other cycles)")
    return finish_figure(fig, ax, f"{s['input']['name']} [{s['input']['unit']}]",
                         f"output [{s['unit']}]", markerscale=5)


def _residual_figure(r: RigDiagnosis) -> Figure:
    fig, ax = plt.subplots(figsize=(7, 3.2))
    t = r.time - r.time[0]
    ax.plot(t, r.reference - r.measured, lw=0.8, color="k", label="reference")
    if r.best is not None:
        ax.plot(t, r.best - r.measured, lw=0.8, color="#d62728",
                label=f"with {r.summary['verdict']}")
    ax.axhline(0.0, color="0.5", lw=0.6)
    return finish_figure(fig, ax, "time [s]", f"model − sensor [{r.summary['unit']}]")


def rig_diagnosis_page(r: RigDiagnosis) -> Page:
    """The page of a rig diagnosis."""
    s = r.summary
    verdict = verdict_text(s).removeprefix("one of ")
    top = s["effects"][0] if s["effects"] else None
    rows = []
    for e in s["effects"]:
        lo, hi = e["shrink_ci95_pct"]
        params = ", ".join(f"{k} {v:+.3g}{unit_suffix(e['units'][k])}"
                           for k, v in e["params"].items())
        rows.append([e["name"], f"{e['rmse_before']:.3f}", f"{e['rmse_after']:.3f}",
                     f"{e['shrink_pct']:+.1f}", _interval(lo, hi), params,
                     e["evidence"]])
    return Page(
        title=f"{RIG_NAMES.get(s['rig'], s['rig'])} diagnosis — {r.stem}",
        subtitle=f"held-out {s['units']}s {s['heldout_units']}; reference: "
                 + s["reference"]["contains"][0],
        cards=[
            Card("verdict", verdict),
            Card("gap, held out", f"{s['gap']['rmse']:.3f}",
                 f"{unit_suffix(s['unit'])} RMS".strip()),
            Card("mean bias (model − sensor)", f"{s['gap']['bias']:+.3f}",
                 unit_suffix(s["unit"]).strip()),
            Card("best shrink", f"{top['shrink_pct']:+.0f}" if top else "–", "%"),
        ],
        sections=[
            Section("Where the reference parts from this session",
                    paragraphs=["Held-out RMSE by phase: " + ", ".join(
                        f"{k} {v:.3f}{unit_suffix(s['unit'])}"
                        for k, v in s["gap"]["per_phase"].items()
                        if math.isfinite(v))],
                    figures={"pv": _pv_figure(r), "residual": _residual_figure(r)}),
            Section("Which effect", paragraphs=[s["verdict_rule"], *s["verdict_reasons"]],
                    tables=[TableBlock(["effect", "before" + unit_suffix(s["unit"]),
                                        "after" + unit_suffix(s["unit"]), "shrink %",
                                        "95 % interval", "fitted", "evidence"], rows)]),
            Section("Next", paragraphs=list(s["next_steps"]) or ["nothing to do: the"
                    " reference holds on this session"]),
        ],
        footer=f"brakethermo {s['run']['brakethermo']}",
        back_href="../index.html",
    )
