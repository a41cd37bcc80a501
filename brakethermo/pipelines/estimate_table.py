"""The estimate's table: the ``estimate.parquet`` columns and the 1-sigma band they carry.

The band is more than the filter's own spread: every reading shares the pyrometer's
calibration error, which the filter cannot see, and the pads' crown balance moves the
spots the filter does not measure (:mod:`brakethermo.pipelines.crown_band`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from brakethermo.pipelines.crown_band import crown_balance_std, crown_sd
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.pipelines.tuning import EstimateTuning
from brakethermo.results.laps import hottest_radius
from brakethermo.thermal.model import DiscFEModel


def band_std(out: np.ndarray, std: np.ndarray, tuning: EstimateTuning,
             temps: list[int] | None = None) -> np.ndarray:
    """1-sigma of the true disc temperature: the filter's spread and the pyrometer's calibration.

    Every reading shares one calibration error (the carbon face's emissivity is known to a
    few hundredths and drifts with glazing and oxidation), so the filter, fed by that one
    sensor, cannot see it; the reported band adds it in quadrature to the temperature
    readouts, in % of the absolute temperature because an emissivity error scales the
    radiance temperature.

    Parameters
    ----------
    out : ndarray (K, m) — degC
        Readouts; the first five are spot1..4 and the contact-band average.
    std : ndarray (K, m) — degC or the readout's unit
        The filter's (or smoother's) 1-sigma of each readout.
    tuning : EstimateTuning
        ``ir_calibration_pct``, 1-sigma in % of the absolute temperature.
    temps : list of int, optional
        The readouts that are temperatures (default the first five).
    """
    cols = list(range(5)) if temps is None else temps
    band = std.copy()
    calib = 0.01 * tuning.ir_calibration_pct * (out[:, cols] + 273.15)
    band[:, cols] = np.hypot(std[:, cols], calib)
    return band


def crown_term(model: DiscFEModel, T0: np.ndarray, q: np.ndarray, h: np.ndarray,
               t_amb: np.ndarray, spot_radii: np.ndarray, spot: int,
               tuning: EstimateTuning, with_nodes: bool) -> np.ndarray:
    """What a crown balance unlike the law's would do at the spots the filter does not
    measure (:mod:`brakethermo.pipelines.crown_band`), 1-sigma (K, 5 + nodes) in degC:
    the four spots, the contact band and, ``with_nodes``, the face nodes. It needs the
    model and the inputs only (``T0`` degC, ``q`` the scaled braking power in W, ``h`` in
    W/(m^2 K), ``t_amb`` degC per step), not the filter: the race runs it beside it."""
    H_spots = model.spot_matrix(spot_radii)
    rows = [H_spots, H_spots[1:4].mean(axis=0, keepdims=True)]
    if with_nodes:
        rows.append(model.spot_matrix(model.radii))
    return crown_balance_std(model, T0, q, h, t_amb, np.vstack(rows), spot,
                             crown_sd(model.weights, tuning.crown_balance_sd))


def reported_band(out: np.ndarray, std: np.ndarray, tuning: EstimateTuning,
                  crown: np.ndarray, node_start: int | None = None) -> np.ndarray:
    """The 1-sigma the outputs carry: the filter's, the pyrometer's calibration
    (:func:`band_std`) and the crown balance's (:func:`crown_term`, its columns the
    spots, the contact band and, with ``node_start``, the face nodes' readouts from that
    column on)."""
    cols = list(range(5))
    if node_start is not None:
        cols += range(node_start, node_start + crown.shape[1] - 5)
    if crown.shape[1] != len(cols):
        raise ValueError(f"a crown term of {crown.shape[1]} columns for {len(cols)} readouts")
    band = band_std(out, std, tuning, cols)
    band[:, cols] = np.hypot(band[:, cols], crown)
    return band


def node_rows_start(out: np.ndarray, tuning: EstimateTuning, model: DiscFEModel
                    ) -> int | None:
    """The column of ``out`` where the face nodes' readouts start (they come last, when
    the smoother gave them: ``race_filter.run_filter``), or None."""
    start = 5 + int(tuning.adapt_power)
    return start if out.shape[1] == start + model.radii.size else None


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
    node_std: np.ndarray | None = None,
) -> pd.DataFrame:
    """The ``estimate.parquet`` table: time and lap, spot1..4 and the contact-band average
    with their bands ``std``, the face nodes (``node_<k>``; with ``node_std`` (K, N),
    degC, the hottest of them ``hottest_radius`` and its ``hottest_radius_std``) and
    deepest-layer nodes
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
    if node_std is not None:  # the window is judged on the hottest radius too: its band
        hot, at = hottest_radius(pd.DataFrame({k: v for k, v in cols.items()
                                               if k.startswith("node_")}))
        cols["hottest_radius"] = hot
        cols["hottest_radius_std"] = node_std[np.arange(hot.size), at]
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
