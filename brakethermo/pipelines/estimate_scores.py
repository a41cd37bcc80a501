"""How an estimate scores itself on a multi-spot session: at the spots it did not feed the
filter, against the open-loop 1D-FE model and the single-spot baseline (the paper's
Tables 3 and 4), with peak errors per braking zone and the coverage of its bands.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from brakethermo.io.plausibility import SENSOR_FLOOR_C  # one floor for every command
from brakethermo.io.session import Session
from brakethermo.pipelines import scoring
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.pipelines.models import DiscCalibration
from brakethermo.report.braking_zones import detect_zones
from brakethermo.thermal.model import DiscFEModel


def score_estimate(
    frame: pd.DataFrame,
    std: np.ndarray,
    filtered: np.ndarray,
    open_loop: np.ndarray,
    inputs: DiscInputs,
    spot: int,
    smoothed: bool,
    zones: np.ndarray | None = None,
) -> dict[str, Any]:
    """The paper's Tables 3 and 4 on a multi-spot session, plus peaks and coverage.

    The reference is the measured spots, as in the paper; the band coverage adds each
    reading's own noise, measured from the reading itself. ``std`` (K, 4) is the filter's
    spread without the pyrometer calibration term: the readings share that error.
    """
    ref = inputs.spots.copy()
    ref[ref <= SENSOR_FLOOR_C] = np.nan
    smooth = frame[[f"spot{i}" for i in range(1, 5)]].to_numpy()
    baseline = scoring.single_spot_baseline(ref[:, spot - 1])
    rows = [
        scoring.score_method("smoother" if smoothed else "filter", smooth, ref),
        *([scoring.score_method("filter", filtered, ref)] if smoothed else []),
        scoring.score_method("open-loop 1D-FE", open_loop, ref),
        scoring.score_method("single-spot", baseline, ref),
    ]
    base = rows[-1]
    validation = [i for i in range(1, 5) if i != spot]
    braking = inputs.braking
    noise = {i: scoring.reading_noise(ref[:, i - 1], inputs.per_reading[i - 1], inputs.steady)
             for i in validation}
    return {
        "reference": "measured spots",
        "measured_spot": spot,
        "table": [r.as_dict() for r in rows],
        "contact_ratio_vs_single_spot": {
            r.method: scoring.ratio(r.contact_rmse, base.contact_rmse) for r in rows[:-1]
        },
        "peak": {
            f"spot{i}": scoring.peak_errors(smooth[:, i - 1], ref[:, i - 1], braking, zones=zones)
            for i in range(1, 5)
        },
        "coverage95": {
            f"spot{i}": scoring.coverage(smooth[:, i - 1], std[:, i - 1], ref[:, i - 1],
                                         extra_var=noise[i] ** 2)
            for i in validation
        },
        # the band estimate.parquet carries (``spot<i>_std``): the filter's spread, the
        # pyrometer's calibration (which these readings share, so it is left out above) and
        # the pads' crown balance
        "coverage95_written_band": {
            f"spot{i}": scoring.coverage(smooth[:, i - 1], frame[f"spot{i}_std"].to_numpy(),
                                         ref[:, i - 1], extra_var=noise[i] ** 2)
            for i in validation if f"spot{i}_std" in frame
        },
        "coverage95_band": "the filter's own spread (plus each reading's noise), without the"
                           " pyrometer calibration term the readings share and the crown"
                           " balance term; coverage95_written_band: the band estimate.parquet"
                           " carries",
    }


def self_scores(session: Session, inputs: DiscInputs, model: DiscFEModel,
                cal: DiscCalibration, x0: np.ndarray, h: np.ndarray, frame: pd.DataFrame,
                std: np.ndarray, readout: np.ndarray, spot_radii: np.ndarray, spot: int,
                smoother: bool) -> tuple[np.ndarray, dict[str, Any]]:
    """A multi-spot session scores its estimate at the spots it did not feed the filter:
    the open-loop 1D-FE baseline, Tables 3/4, peaks and coverage, and whether that is in
    sample (the law identified on this very session)."""
    T_ol = model.open_loop(x0[: model.n_state], inputs.q_brk[:-1], h[:-1], inputs.t_amb[:-1],
                           scale=cal.power_scale)
    open_loop = T_ol @ model.spot_matrix(spot_radii).T
    scores = score_estimate(frame, std[:, :4], readout[:, :4], open_loop, inputs, spot,
                            smoother, zones=detect_zones(inputs.time,
                                                         session.values("brake_pressure_front")))
    in_sample = (cal.identified_on is not None
                 and Path(cal.identified_on).name == session.path.name)
    scores["in_sample"] = in_sample
    scores["reference"] = (
        "measured spots — in sample: the h law, crown weights and k_z were identified on"
        " these spots of this very session; score a session the law did not see for a"
        " held-out figure" if in_sample else
        "measured spots (the law was identified on another session: held out)")
    return open_loop, scores
