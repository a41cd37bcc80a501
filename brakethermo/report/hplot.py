"""The identify-h picture: the written h(V) law and the evidence it rests on."""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pandas as pd
from matplotlib.colors import BoundaryNorm
from matplotlib.figure import Figure

from brakethermo.io.atomic import atomic_path
from brakethermo.thermal.hlaw import HLaw

KMH = 3.6


def _carried_note(ax: Any, carried: tuple[str, ...]) -> None:
    """Say on the plot that straights are judged against the bare law (slipstream)."""
    if "slipstream" in carried:
        ax.text(0.99, 0.09, "the law carries slipstream: straights in another\nbike's wake"
                " sit below the bare law drawn here\nand pull its level's range down",
                transform=ax.transAxes, ha="right", va="bottom", fontsize=8,
                bbox={"fc": "white", "ec": "0.7", "alpha": 0.9})


def _warning_note(fig: Figure, warning: str) -> float:
    """Say below the plot, in red, why the law drawn is not to be trusted; the share of
    the figure's height it takes (0 without a warning), left free by the layout."""
    if not warning:
        return 0.0
    text = textwrap.fill("WARNING: " + warning, 150)
    fig.text(0.5, 0.01, text, ha="center", va="bottom", fontsize=8, color="darkred")
    return 0.03 + 0.028 * text.count("\n")


def plot_h_law(
    samples: pd.DataFrame, fit_mask: np.ndarray, law: HLaw, path: Path, title: str = "",
    law_ukf: HLaw | None = None, straights: pd.DataFrame | None = None,
    level: dict[str, Any] | None = None, carried: tuple[str, ...] = (), warning: str = "",
) -> Path:
    """The written h(V) law and the evidence it was fitted to.

    With ``straights`` (the law refined with the layered model): each off-brake straight's
    own h under that model (points with 1-sigma bars, see
    :mod:`brakethermo.pipelines.h_evidence`) and the law with the 95 % range of its level
    from the straights' scatter; the paper's one-layer UKF samples stay in the background,
    explained, as the method the law does not rest on. Without: the UKF samples the law
    was fitted to (paper §5.1).

    Parameters
    ----------
    samples : pandas.DataFrame
        ``speed`` (m/s), ``h`` and ``h_std`` (W/(m² K)), ``braking`` (bool).
    fit_mask : ndarray of bool
        Off-brake samples (the ones a paper-style fit uses).
    law : HLaw
        The law written to ``h_law.toml``.
    path : Path
        PNG to write (atomically).
    law_ukf : HLaw, optional
        The law fitted to the samples alone, when ``law`` was refined afterwards.
    straights : pandas.DataFrame, optional
        ``speed_kmh``, ``h``, ``h_sd``, ``lap`` per straight.
    level : dict, optional
        ``factor`` and ``ci95`` of the law's level from the straights, ``scatter_pct``.
    carried : tuple of str
        Effects the law carries that change h on some straights (``slipstream``): the
        straights are judged against the bare law, and the figure says so.
    warning : str
        What makes the law implausible (``thermal.hlaw_check``), drawn over the plot so
        that a flat law is not read as a finding; ``""`` = none.
    """
    fig = Figure(figsize=(9.0, 5.5), dpi=110)
    ax = fig.add_subplot()
    v = samples["speed"].to_numpy() * KMH
    h = samples["h"].to_numpy()
    braking = samples["braking"].to_numpy(dtype=bool)
    top = max(360.0, float(np.nanmax(v)) if v.size else 360.0)
    grid_v = np.linspace(0.0, top, 400)
    drawn = _Drawn(v, h, fit_mask, grid_v, law(grid_v / KMH))
    evidence = straights is not None and len(straights) > 0
    if evidence:
        _draw_straights(fig, ax, drawn, straights, level)
        ax.set_title(f"Convection h(V) and the straights it rests on — {title}".rstrip(" —"))
        _carried_note(ax, carried)
    else:
        _draw_ukf_samples(fig, ax, drawn, braking, samples["h_std"].to_numpy())
        ax.set_title(f"Convection coefficient identified by the UKF — {title}".rstrip(" —"))
    knee_kmh = law.knee * law.v_ref * KMH
    ax.axvline(knee_kmh, c="k", ls="--", lw=1)
    ax.text(knee_kmh, 0.02, f"knee {law.knee:.2f}·V_ref = {knee_kmh:.0f} km/h ",
            transform=ax.get_xaxis_transform(), va="bottom", ha="right", fontsize=9)
    bottom = _warning_note(fig, warning)
    ax.set_xlabel("speed [km/h]")
    ax.set_ylabel("h [W/(m² K)]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", markerscale=2, fontsize=8)
    fig.tight_layout(rect=(0.0, bottom, 1.0, 1.0))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return path


@dataclass(frozen=True)
class _Drawn:
    """What both pictures of :func:`plot_h_law` draw: the UKF samples and the written law.

    Attributes
    ----------
    v : ndarray — km/h
        Speed of each UKF sample.
    h : ndarray — W/(m² K)
        The sample's h.
    fit_mask : ndarray of bool
        Off-brake samples (the ones a paper-style fit uses).
    grid_v : ndarray — km/h
        Speeds the law is drawn at.
    h_law : ndarray — W/(m² K)
        The written law at ``grid_v``.
    """

    v: np.ndarray
    h: np.ndarray
    fit_mask: np.ndarray
    grid_v: np.ndarray
    h_law: np.ndarray


def _draw_straights(fig: Figure, ax: Any, d: _Drawn, straights: pd.DataFrame,
                    level: dict[str, Any] | None) -> None:
    """The layered model's evidence: each straight's h (coloured by lap, ±1σ), the law
    with its level's 95 % range, the UKF samples greyed in the background, y range."""
    v, h, fit_mask, grid_v, h_law = d.v, d.h, d.fit_mask, d.grid_v, d.h_law
    ax.scatter(v[fit_mask], h[fit_mask], s=2, c="#b0b0b0", alpha=0.35, lw=0,
               label="paper §5.1 samples (1-layer UKF, off-brake): one layer folds the"
                     "\nskin-to-bulk flow after each stop into h, so they sit low;"
                     " not used")
    if level is not None and np.isfinite(level.get("factor", np.nan)):
        lo, hi = level["ci95"]
        ax.fill_between(grid_v, h_law * lo, h_law * hi, color="k", alpha=0.12, lw=0,
                        label=f"straights' verdict on its level: x{level['factor']:.2f}"
                              f" ({lo:.2f}–{hi:.2f}, 95 %), scatter"
                              f" {level['scatter_pct']:.0f} %")
    laps = straights["lap"].to_numpy()
    bounds = np.arange(laps.min(), laps.max() + 2) - 0.5
    sc = ax.scatter(straights["speed_kmh"], straights["h"], c=laps,
                    cmap=matplotlib.colormaps["viridis"].resampled(bounds.size - 1),
                    norm=BoundaryNorm(bounds, bounds.size - 1),
                    s=26, zorder=3, edgecolors="k", linewidths=0.4,
                    label="each off-brake straight through the layered model (±1σ)")
    ax.errorbar(straights["speed_kmh"], straights["h"], yerr=straights["h_sd"], fmt="none",
                ecolor="k", elinewidth=0.8, alpha=0.6, zorder=2)
    ax.plot(grid_v, h_law, c="k", lw=2.2, label="h(V) written (layered model, output error)")
    shown = np.r_[straights["h"].to_numpy(), h_law[grid_v <= np.nanmax(v, initial=0.0)]]
    lo_y, hi_y = np.nanpercentile(shown, [0.0, 100.0])
    ax.set_ylim(max(0.0, 0.5 * lo_y), 1.35 * hi_y)
    cb = fig.colorbar(sc, ax=ax, pad=0.01, ticks=np.unique(laps))
    cb.set_label("lap")


def _draw_ukf_samples(fig: Figure, ax: Any, d: _Drawn, braking: np.ndarray,
                      h_std: np.ndarray) -> None:
    """The paper's picture: the UKF samples (braking, settling, fitted coloured by their
    posterior σ, ``h_std`` W/(m² K)), the law fitted to them, y range."""
    v, h, fit_mask, grid_v, h_law = d.v, d.h, d.fit_mask, d.grid_v, d.h_law
    other = ~fit_mask & ~braking
    ax.scatter(v[braking], h[braking], s=3, c="#d62728", alpha=0.25, lw=0,
               label="braking (not fitted)")
    ax.scatter(v[other], h[other], s=3, c="#9e9e9e", alpha=0.3, lw=0,
               label="settling after release (not fitted)")
    sc = ax.scatter(v[fit_mask], h[fit_mask], s=4, c=h_std[fit_mask],
                    cmap="viridis_r", lw=0, alpha=0.8, label="off-brake (fitted)")
    ax.plot(grid_v, h_law, c="k", lw=2.2, label="fitted h(V) (paper §5.1)")
    fitted = h[fit_mask]
    if fitted.size:
        lo, hi = np.nanpercentile(fitted, [0.5, 99.5])
        span = hi - lo
        ax.set_ylim(max(0.0, lo - 0.3 * span), hi + 0.3 * span)
    cb = fig.colorbar(sc, ax=ax, pad=0.01)
    cb.set_label("posterior σ of h [W/(m² K)]")
