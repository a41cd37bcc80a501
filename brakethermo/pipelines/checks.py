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
# the friction level against the h law's: pads, temperature and bedding move it by tens
# of %, not threefold (brake pressure in MPa read as bar needs x10)
MAX_POWER_SCALE = 3.0


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
            "is likely wrong (brake pressure, wheel speed), or the pyrometer itself (its "
            "warnings above); do not trust these temperatures"
        )
    return out


def check_power_scale(scale: np.ndarray, braking: np.ndarray) -> list[str]:
    """A warning when the filter had to scale the braking power by more than
    :data:`MAX_POWER_SCALE` (or less than its inverse) to follow the pyrometer.

    Parameters
    ----------
    scale : ndarray (K,) — dimensionless, the power-scale state against the h law's level
    braking : ndarray (K,) of bool — the steps with braking power
    """
    values = np.asarray(scale, dtype=float)[np.asarray(braking, dtype=bool)]
    values = values[np.isfinite(values)]
    if values.size == 0:
        return []
    level = float(np.median(values))
    if 1.0 / MAX_POWER_SCALE <= level <= MAX_POWER_SCALE:
        return []
    return [
        f"IMPLAUSIBLE RESULT: the braking power had to be scaled by {level:.2f} (median while"
        " braking) to follow the pyrometer; no pad's friction changes that much — check the"
        " unit of brake_pressure_front (MPa read as bar gives x10, kPa as bar x0.01) and"
        " the disc's heat share, or the h law (of another disc or session?)"
    ]
