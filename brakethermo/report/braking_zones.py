"""Braking zones from the front brake pressure, their names, and the per-zone table.

A braking zone is a stretch of the 10 Hz grid where the line pressure stays above a
threshold, short releases bridged (a rider who eases off mid-corner is still in the
same zone). The zone's thermal "cycle" runs from its start to the start of the next
zone: the disc heats during braking, peaks just after release, then cools on the
straight; the table reports that cycle.

Zones are named by where they are on the track, the same on every lap and on every
page (lap reports, diagnosis, what-if): braking starts of all flying laps are matched
by lap distance, and the zones braked on in at least half of the flying laps are B1,
B2, … in lap order; an occasional stop (a lift, a second dab) is named after the zone
before it, "B3+". A lap that misses a zone does not renumber the ones after it. The
out-lap's stops are named by the same track position (its distance counted back from the
line it ends on, when it began at the pit exit), not by their order in the lap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from brakethermo.numeric import true_runs

BAR = 1.0e5  # Pa
KMH = 3.6  # (km/h) per (m/s)
SPOTS = ("spot1", "spot2", "spot3", "spot4")
TIME_TOL = 1e-6  # s
ZONE_MATCH_M = 120.0  # m: braking starts closer than this on different laps are one zone


@dataclass(frozen=True)
class ZoneDetection:
    """Thresholds of the braking-zone detector.

    Attributes
    ----------
    on_pa : float — Pa
        Line pressure above which the rider is braking.
    bridge_s : float — s
        Releases shorter than this are bridged into one zone.
    min_duration_s : float — s
        Zones shorter than this (pressure blips) are dropped.
    """

    on_pa: float = 3.0 * BAR
    bridge_s: float = 0.6
    min_duration_s: float = 0.4


def detect_zones(
    time: np.ndarray, pressure_pa: np.ndarray, detection: ZoneDetection | None = None
) -> np.ndarray:
    """Index ranges of the braking zones on the grid.

    Parameters
    ----------
    time : ndarray — s
        Grid time, increasing.
    pressure_pa : ndarray — Pa
        Front brake line pressure on the same grid; NaN counts as not braking.
    detection : ZoneDetection, optional

    Returns
    -------
    ndarray of int, shape (n_zones, 2)
        ``[start, stop)`` grid indices of each zone, in time order.
    """
    det = detection or ZoneDetection()
    braking = np.nan_to_num(np.asarray(pressure_pa, dtype=float), nan=0.0) > det.on_pa
    starts, stops = true_runs(braking).T
    if starts.size == 0:
        return np.empty((0, 2), dtype=np.int64)
    t = np.asarray(time, dtype=float)
    t_ext = np.append(t, t[-1] + (t[-1] - t[-2] if t.size > 1 else 0.1))
    # Bridge short releases: a gap joins its neighbours when it is shorter than bridge_s.
    # Durations are differences of grid times; the tolerance keeps 4 x 0.1 s >= 0.4 s.
    gap = t_ext[starts[1:]] - t_ext[stops[:-1]]
    separate = gap >= det.bridge_s - TIME_TOL
    keep_start = np.concatenate(([True], separate))
    keep_stop = np.concatenate((separate, [True]))
    starts, stops = starts[keep_start], stops[keep_stop]
    long_enough = (t_ext[stops] - t_ext[starts]) >= det.min_duration_s - TIME_TOL
    return np.column_stack((starts[long_enough], stops[long_enough])).astype(np.int64)


def zone_table(
    estimate: pd.DataFrame,
    speed_ms: np.ndarray,
    pressure_pa: np.ndarray,
    zones: np.ndarray,
    window_c: tuple[float, float],
    dist: np.ndarray | None = None,
) -> pd.DataFrame:
    """One row per braking zone: what the disc did through that braking cycle.

    Parameters
    ----------
    estimate : DataFrame
        Estimate frame (OUTPUTS.md): ``time``, ``lap``, ``spot1..4``, ``contact_avg``.
    speed_ms : ndarray — m/s
        Vehicle speed on the same grid.
    pressure_pa : ndarray — Pa
        Brake line pressure on the same grid.
    zones : ndarray of int, shape (n, 2)
        From :func:`detect_zones`.
    window_c : (float, float) — degC
        Operating window.

    Returns
    -------
    DataFrame
        Columns ``zone`` (its track name from ``dist``, m along the lap; without it
        its order in the lap), ``lap``, ``start_s`` (lap time of the
        brake application, s), ``duration_s``, ``entry_speed_kmh``, ``min_speed_kmh``,
        ``peak_pressure_bar``, ``peak_spot1..4`` (degC), ``peak_contact``, ``rise_k``
        (contact-band rise from brake application to peak, K), ``cooling_k`` (drop from
        the peak to the next brake application, K), ``below_s``, ``inside_s``,
        ``above_s`` (contact band vs the window over the cycle, s).
    """
    columns = _zone_columns()
    n = len(estimate)
    if len(zones) == 0 or n == 0:
        return pd.DataFrame({c: pd.Series(dtype=float) for c in columns})
    time = estimate["time"].to_numpy(dtype=float)
    lap = estimate["lap"].to_numpy()
    dt = float(np.median(np.diff(time))) if n > 1 else 0.1
    starts, stops = zones[:, 0], zones[:, 1]
    # A zone's cycle ends where the next zone starts (or where the data ends).
    cycle_end = np.append(starts[1:], n)
    contact = estimate["contact_avg"].to_numpy(dtype=float)
    peak_contact = _cycle_max(contact, starts)
    lap_start_time = pd.Series(time).groupby(lap).transform("min").to_numpy()
    below, inside, above = _window_seconds(contact, starts, dt, window_c)
    p_peak = _cycle_max(np.nan_to_num(np.asarray(pressure_pa, dtype=float), nan=0.0), starts)
    v_min = _braking_min(np.asarray(speed_ms, dtype=float), starts, stops, n)
    zone_lap = lap[starts]
    table = pd.DataFrame(
        {
            "lap": zone_lap,
            "start_s": time[starts] - lap_start_time[starts],
            "duration_s": (stops - starts) * dt,
            "entry_speed_kmh": np.asarray(speed_ms, dtype=float)[starts] * KMH,
            "min_speed_kmh": v_min * KMH,
            "peak_pressure_bar": p_peak / BAR,
            **{f"peak_{s}": _cycle_max(estimate[s].to_numpy(dtype=float), starts)
               for s in SPOTS},
            "peak_contact": peak_contact,
            "rise_k": peak_contact - contact[starts],
            "cooling_k": peak_contact - contact[np.minimum(cycle_end, n - 1)],
            "below_s": below,
            "inside_s": inside,
            "above_s": above,
        }
    )
    names = (zone_names(zones, lap, dist) if dist is not None else
             [f"B{k}" for k in table.groupby("lap").cumcount() + 1])
    table.insert(0, "zone", names)
    return table[columns]


def _zone_columns() -> list[str]:
    """The columns of :func:`zone_table`, in order."""
    return [
        "zone",
        "lap",
        "start_s",
        "duration_s",
        "entry_speed_kmh",
        "min_speed_kmh",
        "peak_pressure_bar",
        *(f"peak_{s}" for s in SPOTS),
        "peak_contact",
        "rise_k",
        "cooling_k",
        "below_s",
        "inside_s",
        "above_s",
    ]


def _cycle_max(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Largest value of each zone's cycle, NaN skipped.

    Parameters
    ----------
    values : ndarray (K,)
        A series on the grid.
    starts : ndarray of int
        First grid index of each zone, increasing.
    """
    # reduceat over the zone starts spans exactly [start_i, start_{i+1}).
    return np.fmax.reduceat(values, starts)


def _window_seconds(contact: np.ndarray, starts: np.ndarray, dt: float,
                    window_c: tuple[float, float]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time of each zone's cycle the contact band spends below, inside and above the window.

    Parameters
    ----------
    contact : ndarray (K,) — degC
        Contact-band average on the grid.
    starts : ndarray of int
        First grid index of each zone, increasing.
    dt : float — s
        Grid step.
    window_c : (float, float) — degC
        Operating window.

    Returns
    -------
    below, inside, above : ndarray — s
    """
    lo, hi = window_c
    below = np.add.reduceat((contact < lo).astype(float), starts) * dt
    above = np.add.reduceat((contact > hi).astype(float), starts) * dt
    valid = np.add.reduceat(np.isfinite(contact).astype(float), starts) * dt
    return below, valid - below - above, above


def _braking_min(speed_ms: np.ndarray, starts: np.ndarray, stops: np.ndarray,
                 n: int) -> np.ndarray:
    """Least speed of each zone while braking (``[start, stop)``), m/s.

    Parameters
    ----------
    speed_ms : ndarray (n,) — m/s
        Vehicle speed on the grid.
    starts, stops : ndarray of int
        ``[start, stop)`` grid indices of each zone.
    n : int
        Grid length.
    """
    # Stops bound the braking part; reduceat over [start, stop) needs interleaved indices.
    brake_idx = np.column_stack((starts, stops)).ravel()
    brake_idx = brake_idx[brake_idx < n]
    return np.fmin.reduceat(speed_ms, brake_idx)[::2][: len(starts)]


def lap_distance(lap: np.ndarray, speed_ms: np.ndarray, dt: float,
                 distance: np.ndarray | None = None) -> np.ndarray:
    """Distance along each lap, m: the logged ``distance`` from each lap's least value
    when it is complete, else the integrated speed.

    Parameters
    ----------
    lap : ndarray (K,) of int
    speed_ms : ndarray (K,) — m/s
    dt : float — s, grid step
    distance : ndarray (K,), optional — m, a logged lap distance
    """
    laps, which = np.unique(lap, return_inverse=True)
    if distance is not None and np.isfinite(distance).all():
        start = np.array([distance[which == j].min() for j in range(laps.size)])
        return distance - start[which]
    out = np.zeros(np.size(speed_ms))
    for j in range(laps.size):
        m = which == j
        out[m] = np.cumsum(np.abs(np.nan_to_num(speed_ms[m]))) * dt
    return out


def zone_clusters(starts: np.ndarray, lap: np.ndarray, dist: np.ndarray
                  ) -> tuple[np.ndarray, list[float]]:
    """Braking starts matched across laps by lap distance.

    Returns
    -------
    ids : ndarray (n,) of int — the cluster of each start, in lap order; -1 when no
        flying lap braked within :data:`ZONE_MATCH_M` of it (an out-lap stop).
    centres : list of float — m, each cluster's first lap distance.
    """
    starts = np.asarray(starts, int)
    centres: list[float] = []
    for d in np.sort(dist[starts[lap[starts] >= 1]]) if starts.size else []:
        if not centres or d - centres[-1] > ZONE_MATCH_M:
            centres.append(float(d))
    ids = np.full(starts.size, -1)
    for i, s in enumerate(starts):
        if centres:
            z = int(np.argmin(np.abs(np.asarray(centres) - dist[s])))
            if abs(centres[z] - dist[s]) <= ZONE_MATCH_M:
                ids[i] = z
    return ids, centres


def cluster_names(ids: np.ndarray, lap_of_start: np.ndarray, n_clusters: int) -> list[str]:
    """The name of each cluster (module docstring): B1… for the zones braked on in at
    least half of the flying laps, "B<k>+" for an occasional stop after B<k>."""
    flying = np.unique(lap_of_start[lap_of_start >= 1])
    laps_in = [np.unique(lap_of_start[(ids == z) & (lap_of_start >= 1)]).size
               for z in range(n_clusters)]
    names, k = [], 0
    for z in range(n_clusters):
        if 2 * laps_in[z] >= max(flying.size, 1):
            k += 1
            names.append(f"B{k}")
        else:
            names.append(f"B{k}+")
    return names


def zone_names(zones: np.ndarray, lap: np.ndarray, dist: np.ndarray) -> list[str]:
    """The track name of each detected zone.

    Parameters
    ----------
    zones : ndarray of int, shape (n, 2)
        ``[start, stop)`` grid rows, in lap order.
    lap : ndarray (K,) of int
        Lap of each grid step; 0 is the out-lap.
    dist : ndarray (K,) — m
        Distance along each lap (:func:`lap_distance`).

    Returns
    -------
    list of str
        The flying laps' name of the zone at that track position (B1…, "B3+"); a stop
        no flying lap shares is "B<k>+" after the regular zone before it. Without a
        flying lap there is nothing to match: named by order, "out B2".
    """
    starts = zones[:, 0] if len(zones) else np.empty(0, int)
    ids, centres = zone_clusters(starts, lap, dist)
    names = cluster_names(ids, lap[starts], len(centres))
    if not centres:
        return [f"out B{k + 1}" for k in range(starts.size)]
    pos = dist[starts].astype(float)
    out_lap = lap[starts] < 1
    if out_lap.any():
        flying = lap >= 1
        length = float(np.median([np.ptp(dist[lap == n]) for n in np.unique(lap[flying])]))
        pos[out_lap] = _out_lap_position(pos[out_lap], float(np.max(dist[~flying])), length,
                                         centres)
    centre = np.asarray(centres)
    out = []
    for p in pos:
        z = int(np.argmin(np.abs(centre - p)))
        if abs(centre[z] - p) <= ZONE_MATCH_M:
            out.append(names[z])
            continue
        # a stop of its own: after the zone before it on the track, as cluster_names
        before = [names[j] for j in range(len(centres)) if centre[j] < p]
        out.append(before[-1].rstrip("+") + "+" if before else "B0+")
    return out


def _out_lap_position(d: np.ndarray, out_end: float, lap_length: float,
                      centres: list[float]) -> np.ndarray:
    """Track position of the out-lap's braking starts, m from the line.

    Parameters
    ----------
    d : ndarray — m
        The out-lap's distance at its braking starts, from its first sample.
    out_end : float — m
        The out-lap's distance at its last sample, where it crosses the line.
    lap_length : float — m
        A flying lap's length (median span of laps 1 on).
    centres : list of float — m
        The flying laps' zone positions (:func:`zone_clusters`).

    Returns
    -------
    ndarray — m
        ``d`` as it is (the log began at the line) or counted back from the line the
        out-lap ends on (it began at the pit exit or mid-lap), whichever puts more of
        its stops on the flying laps' zones (the start on a tie).
    """
    centre = np.asarray(centres)

    def matched(p: np.ndarray) -> int:
        return int(np.sum(np.min(np.abs(p[:, None] - centre[None, :]), axis=1)
                          <= ZONE_MATCH_M)) if p.size else 0

    from_end = lap_length - (out_end - d)
    return from_end if matched(from_end) > matched(d) else d
