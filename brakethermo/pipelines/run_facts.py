"""What an estimate's ``summary.json`` says of the h law and the model it ran: the law,
the mesh and the filter settings, and the warnings where the run is not what the law was
made for (another disc, another layering, speeds beyond its data).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from brakethermo.pipelines.models import DiscCalibration, other_disc
from brakethermo.pipelines.tuning import EstimateTuning
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.model import DiscFEModel


def law_sha256(source: str | Path) -> str | None:
    """SHA-256 of the h law file a run read (None: no file, as a calibration made in
    memory): a later page tells the same law under two spellings of its path (relative,
    absolute) from another law, and a file since rewritten from the one read."""
    try:
        path = Path(source)
        return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None
    except (OSError, ValueError):
        return None


def model_facts(cal: DiscCalibration, tuning: EstimateTuning, model: DiscFEModel
                ) -> dict[str, Any]:
    """The run facts of the law, the mesh and the filter settings."""
    return {
        "h_law": cal.source,
        "h_law_sha256": law_sha256(cal.source) if cal.source else None,
        "nodes": tuning.nodes,
        "layers": tuning.layers,
        "layer_growth": tuning.layer_growth,
        "sigma_crown": tuning.sigma_crown,
        "sigma_temp": tuning.sigma_temp,
        "kz_ratio": cal.kz_ratio,
        "power_scale_prior": cal.power_scale,
        "band_scale_check": cal.band_scale,
        "sigma_meas_c": tuning.sigma_meas,
        "ir_calibration_pct": tuning.ir_calibration_pct,
        "crown_balance_sd": tuning.crown_balance_sd,
        "crown_weights": [float(w) for w in model.weights],
        "filter": "UKF (Merwe scaled sigma points)",
        "smoother": tuning.smoother,
        "adapt_power": tuning.adapt_power,
    }


# faster than the law's data by this factor (6 km/h at 300 km/h) is said
BEYOND_DATA = 1.02


def law_warnings(cal: DiscCalibration, disc: DiscSpec, tuning: EstimateTuning,
                 speed: np.ndarray | None = None) -> list[str]:
    """What the h law was made for that this run is not: another disc, another mesh
    (before the race's own decision, which may refine the mesh for a thinner skin), speeds
    beyond those it was identified on (``speed``, m/s)."""
    warnings = [w for w in (other_disc(cal, disc),) if w]
    v_data = cal.law.x_data * cal.law.v_ref
    top = float(np.nanpercentile(np.abs(speed), 99.9)) if speed is not None and np.isfinite(
        speed).any() else 0.0
    if np.isfinite(v_data) and top > BEYOND_DATA * v_data:
        warnings.append(f"this session runs to {top * 3.6:.0f} km/h, beyond the fastest"
                        f" speed the h law was identified on ({v_data * 3.6:.0f} km/h):"
                        " above it h only grows as the law's power branch does, not as data"
                        " showed; a test session as fast as the race would identify it")
    for what, runs, fitted in (("layers", tuning.layers, cal.layers),
                               ("radial nodes", tuning.nodes, cal.nodes)):
        if fitted is not None and runs != fitted:
            warnings.append(
                f"the model runs {runs} {what} but the h law's k_z ratio was fitted for"
                f" {fitted}; re-run identify-h with the same mesh for best accuracy"
            )
    return warnings
