"""What a disc session can test: the effects whose signature the session barely contains.

An effect the diagnosis cannot confirm is not thereby absent. Some signatures need data a
session may simply not hold: a knee of h(V) needs time above the knee speed, a wrong
emissivity needs readings near the air temperature (above it, the error is a power scale
and an offset that the h law absorbs), a friction level that changes with temperature
needs stops at different disc temperatures. This module measures how much of each
signature a session holds and says, for those below the threshold, why the verdict cannot
speak of them and what data would.
"""

from __future__ import annotations

import numpy as np

from brakethermo.io.plausibility import SENSOR_FLOOR_C
from brakethermo.io.session import Session
from brakethermo.models.disc_effects import KNEE
from brakethermo.pipelines.inputs import DiscInputs

# Where an effect cannot be tested, the effects it reads like are not named alone: a wrong
# emissivity with no reading near the air makes the reading error grow with temperature,
# as a friction rising with temperature makes the heat (an independent generator's wrong
# emissivity was named friction_temperature on two sessions, a third's on one)
READS_LIKE = {"emissivity_error": ("friction_temperature",)}
MIN_ABOVE_KNEE = 0.03  # share of off-brake flying time above the knee speed
MAX_COLD_GAP_C = 100.0  # degC: lowest reading above the air a wrong emissivity can show at
MIN_ONSET_SPREAD_C = 80.0  # degC: spread (10-90 %) of contact temperature at brake onset


def top_speed_kmh(speed: np.ndarray, flying: np.ndarray) -> float:
    """The flying laps' top road speed, km/h (``speed`` in m/s on the 0.1 s grid: a
    channel logged faster is its bin means there, which smooth single-sample spikes)."""
    return float(np.nanmax(np.abs(speed[flying]))) * 3.6


def disc_data_power(
    speed: np.ndarray,
    y: np.ndarray,
    t_amb: np.ndarray,
    braking: np.ndarray,
    flying: np.ndarray,
    v_ref: float,
    floor_c: float,
) -> dict[str, str]:
    """Effects the session can hardly test, each with why and what would test it.

    Parameters
    ----------
    speed : numpy.ndarray — (K,) road speed, m/s.
    y : numpy.ndarray — (K, m) pyrometer readings, degC (NaN where none).
    t_amb : numpy.ndarray — (K,) air temperature, degC.
    braking : numpy.ndarray — (K,) bool, on the brakes.
    flying : numpy.ndarray — (K,) bool, flying laps (the ones the diagnosis scores).
    v_ref : float — m/s, the h law's reference speed (the knee sits at ``KNEE v_ref``).
    floor_c : float — degC, the pyrometer's floor (nothing is read below it).

    Returns
    -------
    dict
        Effect name -> one sentence: what the session lacks and what would test it.
    """
    out: dict[str, str] = {}
    off = flying & ~braking
    v_knee = KNEE * v_ref
    if off.any():
        share = float(np.mean(np.abs(speed[off]) > v_knee))
        top = top_speed_kmh(speed, flying)
        if share < MIN_ABOVE_KNEE:
            out["h_speed_knee"] = (
                f"only {100 * share:.1f} % of the flying laps' off-brake time is above the"
                f" knee speed ({v_knee * 3.6:.0f} km/h; top speed {top:.0f} km/h): too little"
                " to see a knee of h(V) — laps with long straights above"
                f" {v_knee * 3.6:.0f} km/h, or a steady run at top speed with the brakes off,"
                " would test it")
    finite = np.isfinite(y)
    counts = finite.sum(axis=1)
    mean_read = np.where(counts > 0, np.where(finite, y, 0.0).sum(axis=1)
                         / np.maximum(counts, 1), np.nan)
    read = mean_read[flying]
    read = read[np.isfinite(read)]
    if read.size:
        air = float(np.nanmedian(t_amb[flying]))
        lo, hi = float(np.percentile(read, 1)), float(np.percentile(read, 99))
        if lo - air > MAX_COLD_GAP_C:
            near = float(np.mean(read - air <= MAX_COLD_GAP_C))
            seldom = (f"only {100 * near:.1f} % of them" if near > 0 else "none of them")
            out["emissivity_error"] = (
                f"of the readings used on the flying laps (those above {floor_c:.0f} °C:"
                f" below it many pyrometers read nothing), 98 % lie within {lo:.0f}–{hi:.0f}"
                f" °C (1st to 99th percentile), {seldom} within {MAX_COLD_GAP_C:.0f} °C of"
                f" the air ({air:.0f} °C): there a wrong emissivity is mostly a power"
                " scale and an offset the h law absorbs, so a weak one cannot show — a"
                " contact thermocouple on a cold and a hot disc, or a pyrometer of known"
                " emissivity, would test it")
    onsets = np.flatnonzero(np.diff(braking.astype(int)) == 1) + 1
    onsets = onsets[flying[onsets]]
    if onsets.size >= 4:
        t_on = mean_read[onsets]
        t_on = t_on[np.isfinite(t_on)]
        if t_on.size >= 4:
            p10, p90 = np.percentile(t_on, [10, 90])
            if p90 - p10 < MIN_ONSET_SPREAD_C:
                out["friction_temperature"] = (
                    f"the stops start within {p90 - p10:.0f} °C of each other (10–90 %:"
                    f" {p10:.0f}–{p90:.0f} °C): too narrow a range to see friction change"
                    " with temperature — the cold first stops of a run against hot laps,"
                    " or a brake-torque measurement, would test it")
    return out


def untestable_on(session: Session, inputs: DiscInputs, y: np.ndarray, v_ref: float
                  ) -> dict[str, str]:
    """:func:`disc_data_power` of a session as diagnose computes it: its braking zones, its
    flying laps (all of the session when it has none), the readings above the
    pyrometers' floor (identify-h judges the effects it is told to carry by it)."""
    from brakethermo.pipelines.diagnose.layout import full_laps, session_segments, zone_masks

    flying = np.isin(inputs.lap, full_laps(session, inputs))
    if not flying.any():
        flying = np.ones(inputs.lap.size, bool)
    zones = session_segments(session, inputs)[0]
    braking = zone_masks(zones, inputs.lap.size, 0)[0]
    readings = np.where(y > SENSOR_FLOOR_C, y, np.nan)
    return disc_data_power(inputs.speed, readings, inputs.t_amb, braking, flying, v_ref,
                           SENSOR_FLOOR_C)
