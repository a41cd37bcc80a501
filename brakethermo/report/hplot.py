"""The identify-h picture: h samples against speed with the fitted law."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from brakethermo.io.atomic import atomic_path
from brakethermo.thermal.hlaw import HLaw

KMH = 3.6


def plot_h_law(
    samples: pd.DataFrame, fit_mask: np.ndarray, law: HLaw, path: Path, title: str = "",
    law_ukf: HLaw | None = None,
) -> Path:
    """Scatter of UKF h samples (off-brake ones used by the fit) and the fitted law.

    Parameters
    ----------
    samples : pandas.DataFrame
        ``speed`` (m/s), ``h`` and ``h_std`` (W/(m² K)), ``braking`` (bool).
    fit_mask : ndarray of bool
        Samples the law was fitted on.
    law : HLaw
        The law written to ``h_law.toml``.
    path : Path
        PNG to write (atomically).
    law_ukf : HLaw, optional
        The law fitted to the samples alone (paper §5.1), when ``law`` was refined
        afterwards with the layered model.
    """
    fig = Figure(figsize=(9.0, 5.5), dpi=110)
    ax = fig.add_subplot()
    v = samples["speed"].to_numpy() * KMH
    h = samples["h"].to_numpy()
    braking = samples["braking"].to_numpy(dtype=bool)
    other = ~fit_mask & ~braking
    ax.scatter(v[braking], h[braking], s=3, c="#d62728", alpha=0.25, lw=0,
               label="braking (not fitted)")
    ax.scatter(v[other], h[other], s=3, c="#9e9e9e", alpha=0.3, lw=0,
               label="settling after release (not fitted)")
    sc = ax.scatter(v[fit_mask], h[fit_mask], s=4, c=samples["h_std"].to_numpy()[fit_mask],
                    cmap="viridis_r", lw=0, alpha=0.8, label="off-brake (fitted)")
    grid_v = np.linspace(0.0, max(360.0, float(np.nanmax(v)) if v.size else 360.0), 400)
    if law_ukf is not None:
        ax.plot(grid_v, law_ukf(grid_v / KMH), c="k", lw=1.4, ls=":",
                label="fit to these samples (1-layer UKF, paper §5.1)")
        ax.plot(grid_v, law(grid_v / KMH), c="k", lw=2.2,
                label="h(V) refined with the layered model (written)")
    else:
        ax.plot(grid_v, law(grid_v / KMH), c="k", lw=2.2, label="fitted h(V)")
    knee_kmh = law.knee * law.v_ref * KMH
    ax.axvline(knee_kmh, c="k", ls="--", lw=1)
    ax.text(knee_kmh, 0.02, f"knee {law.knee:.2f}·V_ref = {knee_kmh:.0f} km/h ",
            transform=ax.get_xaxis_transform(), va="bottom", ha="right", fontsize=9)
    fitted = h[fit_mask]
    if fitted.size:
        lo, hi = np.nanpercentile(fitted, [0.5, 99.5])
        span = hi - lo
        ax.set_ylim(max(0.0, lo - 0.3 * span), hi + 0.3 * span)
    ax.set_xlabel("speed [km/h]")
    ax.set_ylabel("h [W/(m² K)]")
    ax.set_title(f"Convection coefficient identified by the UKF — {title}".rstrip(" —"))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", markerscale=3, fontsize=9)
    cb = fig.colorbar(sc, ax=ax, pad=0.01)
    cb.set_label("posterior σ of h [W/(m² K)]")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return path
