"""Plausibility of a disc estimate: what no carbon disc and no fitting filter produce.

An input in a wrong unit that slips past the input checks still shows in the result: a
temperature no disc reaches, or a filter whose innovations are far larger than it
expects (mean normalised innovation squared, NIS, ≈1 when the model fits).
"""

from __future__ import annotations

import numpy as np

MIN_TEMP_C = -60.0  # below any air a disc meets
MAX_TEMP_C = 1300.0  # carbon discs run to ~1000 °C; beyond this the input is wrong
MAX_MEAN_NIS = 5.0  # clean sessions give ≈1


def check_estimate_result(temps_c: np.ndarray, nis: np.ndarray) -> list[str]:
    """Warnings for an estimate that cannot be true.

    Parameters
    ----------
    temps_c : ndarray — degC, estimated temperatures (any shape)
    nis : ndarray — normalised innovation squared of the forward filter per step

    Returns
    -------
    list of str
        One line per finding, naming the likely cause; empty for a plausible result.
    """
    out = []
    temps = np.asarray(temps_c, dtype=float)
    bad = int((~np.isfinite(temps)).sum())
    if bad:
        out.append(f"IMPLAUSIBLE RESULT: {bad} estimated temperatures are not finite numbers")
    finite = temps[np.isfinite(temps)]
    if finite.size and (finite.max() > MAX_TEMP_C or finite.min() < MIN_TEMP_C):
        out.append(
            f"IMPLAUSIBLE RESULT: estimated temperatures span {finite.min():.0f}..."
            f"{finite.max():.0f} °C, outside what a carbon disc reaches ({MIN_TEMP_C:.0f}..."
            f"{MAX_TEMP_C:.0f} °C): check the units of brake_pressure_front, "
            "wheel_speed_front and the pyrometer"
        )
    nis = np.asarray(nis, dtype=float)
    mean_nis = float(np.nanmean(nis)) if np.isfinite(nis).any() else float("nan")
    if np.isfinite(mean_nis) and mean_nis > MAX_MEAN_NIS:
        out.append(
            f"IMPLAUSIBLE RESULT: mean NIS {mean_nis:.1f} (≈1 when the model fits the "
            "readings): the inputs disagree with the pyrometer — a channel's unit or scale "
            "is likely wrong (brake pressure, wheel speed); do not trust these temperatures"
        )
    return out
