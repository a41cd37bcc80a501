"""The evidence for a written h(V) law: the convection each straight shows, through the model
the law was written for.

The paper's samples (a one-layer UKF with h as a random walk) fold the skin-to-bulk
conduction of a real disc into h after every stop, so they scatter below a law that is
right. The law identify-h writes comes from the layered model fitted by output error; its
evidence is how each off-brake straight cools under that same model: per straight, the
factor on the law that makes the layered model's cooling (each spot's drop from the
straight's start, so the start's offset does not count) match the measured one. A law
that is right puts those factors around 1 at every speed; a law too high or too low, or
of the wrong shape, shows as factors off 1, or drifting with speed.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from brakethermo.io.session import GRID_DT
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.pipelines.models import DiscCalibration
from brakethermo.pipelines.race_filter import disc_model
from brakethermo.pipelines.scoring import segments
from brakethermo.pipelines.tuning import EstimateTuning
from brakethermo.thermal.disc import DiscSpec

MIN_STRAIGHT_S = 3.0  # s of continuous off-brake cooling a straight needs
MIN_SPEED = 20.0 / 3.6  # m/s: slower is pit lane or a spin, not the law's regime
FACTORS = np.exp(np.linspace(np.log(0.4), np.log(2.5), 41))


def straight_factors(
    inputs: DiscInputs, y: np.ndarray, disc: DiscSpec, cal: DiscCalibration,
    tuning: EstimateTuning, off_brake: np.ndarray,
) -> pd.DataFrame:
    """Per off-brake straight, the factor on the law its cooling shows (module docstring).

    Parameters
    ----------
    inputs : DiscInputs — the session on the model grid.
    y : numpy.ndarray — (K, 4) measured spots, degC (NaN where none).
    disc : DiscSpec
    cal : DiscCalibration — the written law and the structure it was fitted with.
    tuning : EstimateTuning — nodes and layering of that structure.
    off_brake : numpy.ndarray — (K,) bool, steps the law may be judged on.

    Returns
    -------
    pandas.DataFrame
        One row per straight: ``lap``, ``t_start`` (s), ``duration_s``, ``speed_kmh``
        (mean), ``factor`` and ``factor_sd`` (1 sigma, residuals counted once per second),
        ``h`` and ``h_sd`` (W/(m² K): the factor times the law's mean h over the straight).
    """
    model = disc_model(disc, tuning, cal.weights, cal.kz_ratio)
    H = model.spot_matrix(np.asarray(disc.spot_radii))
    h = cal.law(inputs.speed)
    T = model.open_loop(np.full(model.n_state, float(np.nanmean(y[:20])) if np.isfinite(
        y[:20]).any() else float(inputs.t_amb[0])), inputs.q_brk[:-1], h[:-1],
        inputs.t_amb[:-1], scale=cal.power_scale)
    usable = (off_brake & (inputs.lap >= 1) & (np.abs(inputs.speed) > MIN_SPEED)
              & np.isfinite(y).all(axis=1))
    rows = []
    B = FACTORS.size
    u = np.log(FACTORS)
    spot_radii = np.asarray(disc.spot_radii)
    for a, b in segments(usable, round(MIN_STRAIGHT_S / GRID_DT)):
        # the straight starts from the open-loop state moved to the measured spots (each
        # radial node through the thickness by the offset at its radius): a law off by
        # tens of per cent leaves the open-loop disc tens of degrees off, which would
        # change the drop the straight is judged on
        offset = np.interp(model.radii, spot_radii, y[a] - T[a] @ H.T)
        X = np.tile(T[a] + np.repeat(offset, model.layers), (B, 1))
        pred = np.empty((b - a, B, 4))
        for k in range(a, b):
            pred[k - a] = X @ H.T
            if k + 1 < b:
                X = model.step(X, inputs.q_brk[k], h[k] * FACTORS, inputs.t_amb[k],
                               cal.power_scale)
        drop_model = pred - pred[:1]
        drop_meas = (y[a:b] - y[a])[:, None, :]
        sse = np.sum((drop_model - drop_meas) ** 2, axis=(0, 2))
        i = int(np.clip(np.argmin(sse), 1, B - 2))
        c2, c1, _ = np.polyfit(u[i - 1: i + 2], sse[i - 1: i + 2], 2)
        if c2 <= 0:
            continue
        u_best = float(np.clip(-c1 / (2 * c2), u[0], u[-1]))
        if u_best in (u[0], u[-1]):
            continue  # at the edge of the grid: the straight cannot place the law
        n_obs = (b - a) * 4
        s2 = max(float(np.min(sse)) / n_obs, 1e-6)
        per_second = max((b - a) * GRID_DT, 1.0) * 4
        sd_u = float(np.sqrt(2.0 * s2 / (2.0 * c2) * n_obs / per_second))
        factor = float(np.exp(u_best))
        h_mean = float(np.mean(h[a:b]))
        rows.append({
            "lap": int(inputs.lap[a]), "t_start": float(inputs.time[a]),
            "duration_s": (b - a) * GRID_DT, "speed_kmh": float(np.mean(inputs.speed[a:b])) * 3.6,
            "factor": factor, "factor_sd": factor * sd_u,
            "h": factor * h_mean, "h_sd": factor * sd_u * h_mean,
        })
    return pd.DataFrame(rows, columns=["lap", "t_start", "duration_s", "speed_kmh", "factor",
                                       "factor_sd", "h", "h_sd"])


def law_level(straights: pd.DataFrame) -> dict[str, float]:
    """The straights' verdict on the law's level: weighted mean factor and its 95 % range.

    The interval comes from the straight-to-straight scatter (not the fits' own sigmas,
    which ignore what varies from one straight to the next).
    """
    if len(straights) < 2:
        return {"straights": len(straights), "factor": float("nan"),
                "ci95": [float("nan"), float("nan")], "scatter_pct": float("nan")}
    u = np.log(straights["factor"].to_numpy())
    w = 1.0 / np.maximum(straights["factor_sd"].to_numpy() / straights["factor"].to_numpy(),
                         0.02) ** 2
    mean = float(np.sum(w * u) / np.sum(w))
    scatter = float(np.sqrt(np.sum(w * (u - mean) ** 2) / np.sum(w)))
    se = scatter / np.sqrt(len(u))
    return {"straights": len(u), "factor": float(np.exp(mean)),
            "ci95": [float(np.exp(mean - 1.96 * se)), float(np.exp(mean + 1.96 * se))],
            "scatter_pct": 100.0 * scatter}
