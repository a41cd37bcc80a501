"""Laps from ``lap_beacon`` events (CHANNELS.md §1 Laps)."""

from __future__ import annotations

import numpy as np

from brakethermo.errors import DataError
from brakethermo.io.session import Lap

# A beacon exactly on a grid point starts its lap there despite float round-off, s.
_ON_GRID = 1e-9


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
        per beacon; with no beacon, the whole session as lap 0.
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
    if starts.size == 0 or starts[0] > _ON_GRID:
        starts = np.concatenate(([0.0], starts))
        numbers = np.concatenate(([0], numbers))
    ends = np.append(starts[1:], max(end_s, starts[-1]))
    laps = tuple(
        Lap(int(n), float(s), float(e - s))
        for n, s, e in zip(numbers.tolist(), starts.tolist(), ends.tolist(), strict=True)
    )
    idx = np.searchsorted(starts, t_grid + _ON_GRID, side="right") - 1
    return laps, numbers[np.clip(idx, 0, None)]
