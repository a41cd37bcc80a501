"""The estimate's table: the ``estimate.parquet`` columns and the 1-sigma band they carry.

The band is more than the filter's own spread: every reading shares the pyrometer's
calibration error, which the filter cannot see, and the pads' crown balance moves the
spots the filter does not measure (:mod:`brakethermo.pipelines.crown_band`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from brakethermo.pipelines.crown_band import crown_balance_std
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.pipelines.tuning import EstimateTuning
from brakethermo.thermal.model import DiscFEModel


def band_std(out: np.ndarray, std: np.ndarray, tuning: EstimateTuning) -> np.ndarray:
    """1-sigma of the true disc temperature: the filter's spread and the pyrometer's calibration.

    Every reading shares one calibration error (the carbon face's emissivity is known to a
    few hundredths and drifts with glazing and oxidation), so the filter, fed by that one
    sensor, cannot see it; the reported band adds it in quadrature to the spot and
    contact-band readouts, in % of the absolute temperature because an emissivity error
    scales the radiance temperature.

    Parameters
    ----------
    out : ndarray (K, m) — degC
        Readouts; the first five are spot1..4 and the contact-band average.
    std : ndarray (K, m) — degC or the readout's unit
        The filter's (or smoother's) 1-sigma of each readout.
    tuning : EstimateTuning
        ``ir_calibration_pct``, 1-sigma in % of the absolute temperature.
    """
    band = std.copy()
    calib = 0.01 * tuning.ir_calibration_pct * (out[:, :5] + 273.15)
    band[:, :5] = np.hypot(std[:, :5], calib)
    return band


def reported_band(out: np.ndarray, std: np.ndarray, tuning: EstimateTuning,
                  model: DiscFEModel, T0: np.ndarray, q: np.ndarray, h: np.ndarray,
                  t_amb: np.ndarray, spot_radii: np.ndarray, spot: int) -> np.ndarray:
    """The 1-sigma the outputs carry: the filter's, the pyrometer's calibration
    (:func:`band_std`) and what a crown balance unlike the law's would do at the spots
    the filter does not measure (:mod:`brakethermo.pipelines.crown_band`)."""
    band = band_std(out, std, tuning)
    H_spots = model.spot_matrix(spot_radii)
    H = np.vstack([H_spots, H_spots[1:4].mean(axis=0)])
    crown = crown_balance_std(model, T0, q, h, t_amb, H, spot, tuning.crown_balance_sd)
    band[:, :5] = np.hypot(band[:, :5], crown)
    return band


def above_air(out: np.ndarray, t_amb: np.ndarray) -> np.ndarray:
    """The spots and the contact average (``out[:, :5]``, degC) as published: a disc is
    never colder than the air (degC) around it, so the estimate is projected onto
    T >= T_amb (estimate projection of a constrained Kalman filter, Simon & Chia 2002).
    Without it the smoother, with no reading below the pyrometer floor, can start the
    disc colder."""
    out = np.array(out, dtype=float, copy=True)
    out[:, :5] = np.fmax(out[:, :5], np.asarray(t_amb)[:, None])
    return out


def estimate_frame(
    inputs: DiscInputs,
    model: DiscFEModel,
    states: np.ndarray,
    out: np.ndarray,
    std: np.ndarray,
    tuning: EstimateTuning,
    h: np.ndarray,
    online: dict[str, int],
) -> pd.DataFrame:
    """The ``estimate.parquet`` table: time and lap, spot1..4 and the contact-band average
    with their bands ``std``, the face nodes (``node_<k>``) and deepest-layer nodes
    (``mid_<k>``), the power scale and online effect factors the filter learned, the
    braking power and h."""
    cols: dict[str, np.ndarray] = {"time": inputs.time, "lap": inputs.lap.astype(np.int64)}
    floor = inputs.t_amb  # every node, too, is never colder than the air
    out = above_air(out, floor)
    for i in range(4):
        cols[f"spot{i + 1}"] = out[:, i]
        cols[f"spot{i + 1}_std"] = std[:, i]
    cols["contact_avg"] = out[:, 4]
    cols["contact_avg_std"] = std[:, 4]
    for k, j in enumerate(model.face_index):
        cols[f"node_{k}"] = np.fmax(states[:, j], floor)
    if model.layers > 1:
        mid = model.face_index + model.layers - 1
        for k, j in enumerate(mid):
            cols[f"mid_{k}"] = np.fmax(states[:, j], floor)
    if tuning.adapt_power:
        cols["power_scale"] = out[:, 5]
        cols["power_scale_std"] = std[:, 5]
    for name, j in online.items():  # online effect factors, e.g. kz_factor, h_factor
        cols[name] = states[:, j]
    cols["braking_power"] = inputs.q_brk
    cols["h"] = h
    return pd.DataFrame(cols)
