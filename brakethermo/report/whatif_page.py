"""The ``whatif`` page: base and scenarios on the same axes, and a table a crew chief reads
in ten seconds. Takes the summary and the ``whatif.parquet`` table (plain data)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from brakethermo.report.page import (
    Card,
    Page,
    Section,
    TableBlock,
    finish_figure,
    number_text,
    write_page,
)
from brakethermo.results.laps import lap_label

# 12 qualitative colours (tab10 without its grey, the as-run line's, and the green of the
# window, then three darker tab20b/c hues): seven scenarios repeated the first colour
COLORS = ("#1f77b4", "#d62728", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#bcbd22",
          "#17becf", "#393b79", "#843c39", "#7b4173", "#637939")
BASE_COLOR = "#444444"
# past the palette, a scenario keeps a colour but changes its line style and bar hatch
LINESTYLES = ("-", "--", ":", "-.")
HATCHES = ("", "//", "..", "xx")
TITLE_SEP = " | "  # a scenario's own label joins its changes with commas


def scenario_style(j: int) -> tuple[str, str, str]:
    """Colour, line style and bar hatch of the ``j``-th scenario (0-based): distinct for
    ``len(COLORS) * len(LINESTYLES)`` scenarios."""
    turn = (j // len(COLORS)) % len(LINESTYLES)
    return COLORS[j % len(COLORS)], LINESTYLES[turn], HATCHES[turn]


def _f(x: float | None, spec: str = ".0f") -> str:
    text = number_text(x, spec)
    # a change that rounds to nothing is no change: "-0" (or "+0") reads as a direction
    return text.lstrip("+-") if text != "–" and float(text) == 0.0 else text


def shown(label: str) -> str:
    """A scenario label as people read it (the summary keys keep ASCII units)."""
    return label.replace(" degC", " °C")


def _suffixes(n: int) -> list[str]:
    return ["" if j == 1 else f"_{j}" for j in range(1, n + 1)]


def contact_figure(frame: pd.DataFrame, labels: Sequence[str], window: Sequence[float]
                   ) -> Figure:
    """Contact-band temperature over the session: base and each scenario with its 95 % band."""
    fig, ax = plt.subplots(figsize=(11, 4.2))
    t = frame["time"].to_numpy() / 60.0
    ax.axhspan(window[0], window[1], color="#2ca02c", alpha=0.07, lw=0)
    for w in window:
        ax.axhline(w, color="#2ca02c", lw=0.8, ls="--")
    ax.plot(t, frame["base_contact_avg"], color=BASE_COLOR, lw=1.0, label="as run (estimate)")
    for j, (sfx, lab) in enumerate(zip(_suffixes(len(labels)), labels, strict=True)):
        c = frame[f"contact_avg{sfx}"].to_numpy()
        s = frame[f"contact_avg_std{sfx}"].to_numpy()
        col, ls, _ = scenario_style(j)
        ax.fill_between(t, c - 1.96 * s, c + 1.96 * s, color=col, alpha=0.15, lw=0)
        ax.plot(t, c, color=col, ls=ls, lw=1.0, label=f"{shown(lab)} (95 % band)")
    ax.set_title("Contact-band temperature: as run and replayed with each change")
    # beside the axes, never over the traces, however many scenarios
    return finish_figure(fig, ax, "time, min", "contact band, °C", loc="upper left",
                         bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def lap_figure(laps: Sequence[Mapping[str, Any]], labels: Sequence[str],
               window: Sequence[float], mu_varies: bool) -> Figure:
    """Per lap: peak contact (95 %), time in the window, heat to the tyre, and the least
    μ/μ_nom while braking — or, when the law carries no μ(T), the hottest radius."""
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    n = [row["lap"] for row in laps]
    x = np.arange(len(n))
    keys = ["base", *labels]
    width = 0.8 / len(keys)
    panels = (("peak_contact_c", "peak contact band, °C"),
              ("time_in_window_pct", "time in window, %"),
              ("tyre_heat_kj", "heat radiated to the tyre, kJ per lap (one disc)"),
              ("mu_rel_min", "least μ/μ_nom while braking") if mu_varies else
              ("hottest_radius_c", "hottest radius, °C"))
    for ax, (key, title) in zip(axes.ravel(), panels, strict=True):
        for j, k in enumerate(keys):
            vals = np.array([row[k][key] for row in laps], float)
            col, _, hatch = (BASE_COLOR, "-", "") if k == "base" else scenario_style(j - 1)
            err = None
            if key == "peak_contact_c" and k != "base":
                err = np.array([row[k]["peak_contact_band95_c"] for row in laps], float)
            ax.bar(x + (j - (len(keys) - 1) / 2) * width, vals, width, yerr=err, color=col,
                   hatch=hatch, alpha=0.85, capsize=2,
                   label="as run" if k == "base" else shown(k))
        if key in ("peak_contact_c", "hottest_radius_c"):
            for w in window:
                ax.axhline(w, color="#2ca02c", lw=0.8, ls="--")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3, axis="y")
    for ax in axes[1]:
        ax.set_xticks(x, [str(v) for v in n])
        ax.set_xlabel("lap")
    # one legend for the four panels, below them: inside a panel it covered the bars
    handles, names = axes[0, 0].get_legend_handles_labels()
    rows = math.ceil(len(names) / 4)
    fig.legend(handles, names, loc="lower center", ncols=min(4, len(names)), fontsize=8,
               frameon=False)
    fig.tight_layout(rect=(0.0, min(0.4, 0.035 * rows + 0.01), 1.0, 1.0))
    return fig


def _table(laps: Sequence[Mapping[str, Any]], labels: Sequence[str]) -> TableBlock:
    header = ["lap", "as run: peak °C", "in window %", "tyre kJ", "μ min"]
    for lab in labels:
        header += [f"{shown(lab)}: peak °C (95 %)", "in window %", "above s", "tyre kJ", "μ min"]
    rows = []
    for row in laps:
        b = row["base"]
        cells: list[object] = [lap_label(row["lap"]), _f(b["peak_contact_c"]),
                               _f(b["time_in_window_pct"]), _f(b.get("tyre_heat_kj"), ".1f"),
                               _f(b.get("mu_rel_min"), ".2f")]
        for lab in labels:
            s = row[lab]
            cells += [f"{_f(s['peak_contact_c'])} ± {_f(s['peak_contact_band95_c'])}",
                      _f(s["time_in_window_pct"]), _f(s["time_above_s"], ".1f"),
                      _f(s["tyre_heat_kj"], ".1f"), _f(s["mu_rel_min"], ".2f")]
        rows.append(cells)
    return TableBlock(header, rows, "Per lap, contact band; ± is the 95 % band of the"
                      " scenario's peak (estimate, h-law uncertainty, model allowance).")


def _band_text(run: Mapping[str, Any]) -> str:
    """How the 95 % band is made; with no replays over the law (``--draws 0``) it has no
    spread of them ("the spread of 0 replays" read as a spread that was measured)."""
    law = (f"the spread of {run['draws']} replays over the h law's level (1-sigma"
           f" {100 * run['h_rel_sigma']:.0f} %)" if run["draws"] > 0 else
           "no spread over the h law's level (--draws 0: the law's uncertainty is left"
           " out, so the band is narrower than the change's own)")
    return (f"95 % band = the estimate's own band, {law}, and {run['model_error_pct']:g} %"
            " of the change as a model-structure allowance, in quadrature.")


def whatif_page(summary: Mapping[str, Any], frame: pd.DataFrame) -> Page:
    """The page of one ``whatif`` run."""
    labels = [s["label"] for s in summary["scenarios"]]
    window = summary["run"]["window_c"]
    laps = summary["laps"]
    mu_varies = any(abs(row[k]["mu_rel_min"] - 1.0) > 1e-9 for row in laps
                    for k in ("base", *labels) if math.isfinite(row[k]["mu_rel_min"]))
    flying = [row for row in laps if row["lap"] > 0] or laps
    cards = []
    for lab in labels:
        d = [row[lab]["peak_contact_c"] - row["base"]["peak_contact_c"] for row in flying]
        w = [row[lab]["time_in_window_pct"] - row["base"]["time_in_window_pct"]
             for row in flying]
        cards.append(Card(f"{shown(lab)}: lap peak change, mean of the flying laps",
                          _f(float(np.mean(d)), "+.0f"), "°C"))
        cards.append(Card(f"{shown(lab)}: window change, mean of the flying laps",
                          _f(float(np.mean(w)), "+.0f"), "% of lap"))
    main = Section(
        "Contact band as run and with each change",
        paragraphs=[
            f"Session {summary['session']}, disc {summary['run']['disc']}, window"
            f" {window[0]:g}–{window[1]:g} °C, h law {summary['run']['h_law']}.",
            "Each scenario replays the session's own laps: the same speed trace and braking"
            " power at every stop, the laps' own model corrections kept, so the model"
            " predicts the change and the measured laps fix the rest.",
        ],
        tables=[_table(laps, labels)],
        figures={"contact": contact_figure(frame, labels, window),
                 "laps": lap_figure(laps, labels, window, mu_varies)},
        notes=list(summary["assumptions"]),
    )
    run = summary["run"]
    facts = Section("How the band is made", paragraphs=[
        _band_text(run),
        f"Tyre view: rim {run['tyre_view']['rim_radius_m']:g} m, tyre"
        f" {run['tyre_view']['tyre_radius_m']:g} m, gap {run['tyre_view']['gap_m']:g} m,"
        f" sidewall {run['tyre_view']['carcass_c']:g} °C, ε {run['tyre_view']['emissivity']:g}.",
    ] + [f"warning: {w}" for w in run.get("warnings", [])])
    return Page(title="What if", subtitle=TITLE_SEP.join(map(shown, labels)), cards=cards,
                sections=[main, facts], back_href="../index.html",
                footer=f"brakethermo {run['brakethermo']}")


def write_whatif_page(summary: Mapping[str, Any], frame: pd.DataFrame, folder: Path) -> Path:
    """Write ``folder/index.html`` and its PNGs; return the page path."""
    return write_page(whatif_page(summary, frame), Path(folder))
