"""Laps from ``lap_beacon`` events (CHANNELS.md §1 Laps)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.session import Lap

# A beacon exactly on a grid point starts its lap there despite float round-off, s.
_ON_GRID = 1e-9
# Largest lap number taken as real (a 24 h race at 1 min a lap is 1440 laps).
MAX_LAP = 9999
# A crossing sooner than this after the previous one is a beacon bounce, s ...
MIN_LAP_S = 5.0
# ... or than this fraction of the median lap, whichever is longer.
MIN_LAP_FRACTION = 0.25
# A lap longer than this many median laps is reported (a beacon was probably missed).
LONG_LAP_FACTOR = 1.8
# Flying laps of one track differ by far less than this factor (traffic, rain, safety car)
IMPLAUSIBLE_LAP_RATIO = 3.0


def laps_from_beacons(
    t_beacon: np.ndarray, lap_number: np.ndarray, t_grid: np.ndarray, end_s: float, *,
    path: object = None, channel: str = "lap_beacon",
) -> tuple[tuple[Lap, ...], np.ndarray]:
    """Lap list and per-grid-point lap number.

    Parameters
    ----------
    t_beacon : ndarray
        Beacon crossing times, s, sorted.
    lap_number : ndarray
        Number of the lap that starts at each crossing.
    t_grid : ndarray
        The 10 Hz grid, s.
    end_s : float
        End of the session (last sample of any channel), s; the last lap ends there.

    Returns
    -------
    laps : tuple of Lap
        Lap 0 (out-lap) from 0 s to the first beacon if that is later than 0, then one lap
        per beacon; with no beacon, the whole session as lap 0. A first beacon numbered 0
        starts lap 0 at 0 s (no lap is listed twice); one numbered N >= 2 says the log
        began inside lap N - 1: the stretch before it is lap 0 marked ``cut_start``.
    lap : ndarray of int64
        Lap number of every grid point.

    Raises
    ------
    DataError
        A beacon value that is not a whole non-negative number.
    """
    if lap_number.size and (
        (lap_number != np.round(lap_number)).any() or (lap_number < 0).any()
    ):
        bad = lap_number[(lap_number != np.round(lap_number)) | (lap_number < 0)][0]
        raise DataError(
            f"beacon value {bad!r} is not a lap number (a whole number >= 0)",
            path=path, channel=channel,
        )
    numbers = lap_number.astype(np.int64)
    starts = t_beacon.astype(np.float64)
    # a first beacon of lap N >= 2 after the start: the log began inside lap N - 1; the
    # stretch before it stays lap 0 (no flying lap: its lap distance does not start at the
    # line) and is marked cut, so that no output counts it as a lap
    cut = bool(numbers.size and numbers[0] >= 2 and starts[0] > _ON_GRID)
    if starts.size and numbers[0] == 0:
        starts = starts.copy()
        starts[0] = 0.0  # a beacon "lap 0" marks the out-lap, which began with the session
    elif starts.size == 0 or starts[0] > _ON_GRID:
        starts = np.concatenate(([0.0], starts))
        numbers = np.concatenate(([0], numbers))
    ends = np.append(starts[1:], max(end_s, starts[-1]))
    laps = tuple(
        Lap(int(n), float(s), float(e - s), cut_start=cut and i == 0)
        for i, (n, s, e) in enumerate(zip(numbers.tolist(), starts.tolist(), ends.tolist(),
                                          strict=True))
    )
    idx = np.searchsorted(starts, t_grid + _ON_GRID, side="right") - 1
    return laps, numbers[np.clip(idx, 0, None)]


SHORT_DISTANCE = 0.9  # of the typical flying lap's distance: a last lap under it is cut


def mark_cut_end(laps: tuple[Lap, ...], lap: np.ndarray, speed: np.ndarray | None,
                 dt: float) -> tuple[Lap, ...]:
    """``laps`` with the last one marked :attr:`Lap.cut_end` when the distance ridden in it
    (speed integrated, m) is under :data:`SHORT_DISTANCE` of the median of the flying laps
    before it. No beacon ever closes the last lap, so its duration alone cannot tell a
    whole lap ended at the line from an in-lap: an independent generator's session ended
    in the pits 55 % round its last lap, slowly enough to last a lap's time, and that
    lap was given a lap time and used as a flying lap.

    Parameters
    ----------
    laps : tuple of Lap
    lap : ndarray (K,) of int — lap of each grid point.
    speed : ndarray (K,) or None — m/s on the grid (None: no speed channel, laps as given).
    dt : float — s, grid step.
    """
    if speed is None or len(laps) < 2 or laps[-1].lap < 1:
        return laps
    v = np.nan_to_num(np.abs(np.asarray(speed, float)))
    dist = np.bincount(np.asarray(lap, np.int64), weights=v * dt)  # m ridden per lap
    before = [dist[x.lap] for x in laps[:-1] if x.lap >= 1 and not x.cut_start]
    if not before or dist[laps[-1].lap] >= SHORT_DISTANCE * float(np.median(before)):
        return laps
    return (*laps[:-1], replace(laps[-1], cut_end=True))


MIN_RESET_GAP_S = 20.0  # s: resets of a lap-distance channel closer than this are noise


def beacons_from_distance(t: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Times where a lap-distance channel goes back to the line (s), for a log without a
    beacon: a step down by more than half the largest distance, to under a tenth of it,
    at least :data:`MIN_RESET_GAP_S` after the previous one; none for a distance that never
    resets (a cumulative odometer).

    Parameters
    ----------
    t : ndarray — s, sorted
    d : ndarray — distance along the lap, any unit
    """
    if d.size < 2 or not np.isfinite(d).any():
        return np.empty(0)
    top = float(np.nanmax(d))
    if not top > 0.0:
        return np.empty(0)
    steps = np.flatnonzero((np.diff(d) < -0.5 * top) & (d[1:] < 0.1 * top)) + 1
    times: list[float] = []
    for i in steps:
        if not times or t[i] - times[-1] >= MIN_RESET_GAP_S:
            times.append(float(t[i]))
    return np.array(times)


def _drop_bounces(t: np.ndarray, v: np.ndarray, channel: str, warnings: list[str]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Crossings too soon after the previous one (beacon bounces) dropped, and said."""
    if t.size < 2:
        return t, v
    step = np.diff(t)
    min_lap = max(MIN_LAP_S, MIN_LAP_FRACTION * float(np.median(step)))
    keep = np.ones(t.size, dtype=bool)
    last = t[0]
    for i in range(1, t.size):  # beacons are few (one per lap): a plain loop
        if t[i] - last < min_lap:
            keep[i] = False
        else:
            last = t[i]
    if not keep.all():
        gone = t[~keep]
        warnings.append(
            f"lap beacon '{channel}': {gone.size} crossing(s) less than {min_lap:.1f} s after"
            " the previous one dropped as beacon bounces (at t = "
            + ", ".join(f"{x:.2f}" for x in gone[:5]) + (" ..." if gone.size > 5 else "")
            + " s)"
        )
        t, v = t[keep], v[keep]
    return t, v


def _renumbered(t: np.ndarray, v: np.ndarray, valid: np.ndarray, channel: str,
                warnings: list[str]) -> np.ndarray:
    """Whole increasing lap numbers: a count-down or a minority of bad values renumbered
    in crossing order, and said."""
    increasing = bool(valid.all() and (np.diff(v) > 0).all())
    if v.size >= 2 and valid.all() and (np.diff(v) < 0).all():
        warnings.append(
            f"lap beacon '{channel}': values " + ", ".join(f"{x:g}" for x in v[:12])
            + (" ..." if v.size > 12 else "") + " count down (laps remaining, not lap"
            " numbers); laps renumbered 1, 2, ... in crossing order, the out-lap before the"
            " first crossing is lap 0"
        )
        v = 1.0 + np.arange(v.size, dtype=np.float64)
        increasing = True
    if v.size and not increasing:
        first = int(np.argmax(valid))
        start = max(int(v[first]) - first, 0)
        fixed = start + np.arange(v.size, dtype=np.float64)
        changed = np.flatnonzero(fixed != v)
        warnings.append(
            f"lap beacon '{channel}': values "
            + ", ".join(f"{x:g}" for x in v[:12]) + (" ..." if v.size > 12 else "")
            + " are not increasing lap numbers; laps renumbered in crossing order from"
            f" {start} ("
            + ", ".join(f"t = {t[i]:.2f} s: {v[i]:g} -> {int(fixed[i])}" for i in changed[:5])
            + (" ..." if changed.size > 5 else "") + ")"
        )
        v = fixed
    return v


def validate_beacons(
    t_beacon: np.ndarray, lap_number: np.ndarray, *, path: object = None,
    channel: str = "lap_beacon",
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Check beacon crossings and repair them, saying what was done.

    * A crossing closer to the previous one than :data:`MIN_LAP_FRACTION` of the median
      lap (or :data:`MIN_LAP_S`) is a bounce of the beacon and is dropped.
    * Lap numbers must be whole, within 0..:data:`MAX_LAP` and increasing. When a
      minority of them is not (a value that steps back, repeats, or is garbage such as
      1e20), the laps are renumbered in crossing order from the first good value.
    * A lap more than :data:`LONG_LAP_FACTOR` times the median is reported (a missed
      beacon), as are lap numbers that are skipped; both are kept as logged.

    Parameters
    ----------
    t_beacon : ndarray — s, sorted
    lap_number : ndarray
        Beacon values as logged.

    Returns
    -------
    t_beacon, lap_number : ndarray
        The crossings kept and their lap numbers (whole, increasing).
    warnings : list of str

    Raises
    ------
    DataError
        Most beacon values are not lap numbers (the channel is probably not a beacon).
    """
    warnings: list[str] = []
    t = np.asarray(t_beacon, dtype=np.float64)
    v = np.asarray(lap_number, dtype=np.float64)
    t, v = _drop_bounces(t, v, channel, warnings)
    valid = np.isfinite(v) & (v == np.round(v)) & (v >= 0) & (v <= MAX_LAP)
    if v.size and valid.sum() * 2 < v.size:
        bad = v[~valid][0]
        raise DataError(
            f"beacon value {bad!r} is not a lap number (a whole number 0..{MAX_LAP}), nor are"
            f" {int((~valid).sum())} of the {v.size} values; is '{channel}' really the lap"
            " beacon? Fix the alias table (--aliases FILE)",
            path=path, channel=channel,
        )
    v = _renumbered(t, v, valid, channel, warnings)
    skipped = np.flatnonzero(np.diff(v) > 1)
    if skipped.size:
        warnings.append(
            f"lap beacon '{channel}': no crossing for lap(s) "
            + ", ".join(f"{int(v[i]) + 1}" + (f"-{int(v[i + 1]) - 1}" if v[i + 1] - v[i] > 2
                                              else "") for i in skipped[:5])
            + "; the lap before each gap is kept as logged (it spans the missing laps)"
        )
    if t.size >= 4:
        step = np.diff(t)
        median = float(np.median(step))
        long = np.flatnonzero(step > LONG_LAP_FACTOR * median)
        if long.size and not skipped.size:
            warnings.append(
                f"lap beacon '{channel}': lap(s) "
                + ", ".join(f"{int(v[i])} ({step[i]:.1f} s)" for i in long[:5])
                + f" last more than {LONG_LAP_FACTOR:g} times the median lap ({median:.1f} s):"
                " a missed beacon? Kept as logged"
            )
    return t, v, warnings


def lap_length_warnings(laps: tuple[Lap, ...], channel: str = "lap_beacon") -> list[str]:
    """Say when flying laps differ in length beyond what one track allows.

    A misplaced or extra beacon splits a session into a short and a long "lap"; a
    command that trains or scores by lap would use them as if they were laps. The out-lap
    (0) and the last lap (it ends with the log, often in the pits) are not compared.
    """
    flying = [lap for lap in laps[:-1] if lap.lap > 0]
    if len(flying) < 2:
        return []
    d = np.array([lap.duration_s for lap in flying])
    if d.max() <= IMPLAUSIBLE_LAP_RATIO * d.min():
        return []
    return [
        f"lap beacon '{channel}': laps of implausibly different length ("
        + ", ".join(f"lap {lap.lap}: {lap.duration_s:.1f} s" for lap in flying[:8])
        + (" ..." if len(flying) > 8 else "")
        + "): a misplaced or extra beacon? Per-lap results of these laps are not comparable;"
        " fix the beacon channel"
    ]
