"""Native-rate channels onto a uniform grid, anti-aliased, gaps reported.

The disc pipelines use the 10 Hz grid of OUTPUTS.md; the rig pipelines choose their own
rate (:func:`brakethermo.io.load.load_session`, ``rate_hz``). Below, ``dt`` is the grid
spacing (0.1 s on the disc grid). Each grid point ``t_k = k dt`` owns the bin ``[t_k -
dt/2, t_k + dt/2)``. The samples of a bin are averaged (a box filter of width dt: zeros
at 1/dt, 2/dt ... Hz, so content above the grid's Nyquist frequency is strongly
attenuated instead of folding back) together with their mean time; the grid value is the
linear interpolation of these (mean time, mean value) points. A ramp is therefore
reproduced exactly at any sample rate, a constant stays constant, and bins without a
sample are bridged linearly from their neighbours. The first and last grid points see
only half a bin of data (there is none beyond the session), so their filtering is
weaker. A bin inside a spacing between native samples longer than the gap limit stays
NaN and the gap is reported.

IR temperature channels first go through a Hampel filter at their native rate: a sample
further than ``n_sigma`` robust standard deviations (and at least ``floor``) from the
median of its window is an isolated spike and is replaced by that median.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from brakethermo.errors import DataError
from brakethermo.io.session import GRID_DT

_MAD_TO_SIGMA = 1.4826  # MAD of a normal distribution, in standard deviations
_EDGE_TOL = 1e-6  # bins; 100 ns, far above float round-off, far below any sample spacing


@dataclass(frozen=True)
class Resampled:
    """One channel on the grid.

    Attributes
    ----------
    values : ndarray
        Grid values (NaN before the first / after the last sample and inside gaps).
    gaps : tuple of (float, float)
        ``(start_s, duration_s)`` of each spacing longer than the gap limit.
    rate_hz : float
        Native rate, 1 / median sample spacing, Hz (0 for fewer than two samples).
    spikes : int
        Samples replaced by the Hampel filter.
    """

    values: np.ndarray
    gaps: tuple[tuple[float, float], ...]
    rate_hz: float
    spikes: int = 0


MAX_BACK_S = 1.0  # s: a step back in time beyond this is a clock reset, not buffering


def grid(end_s: float, dt: float = GRID_DT) -> np.ndarray:
    """The grid ``0, dt, 2 dt, ...`` covering ``[0, end_s]``, s (10 Hz by default)."""
    n = int(np.floor(end_s / dt + 0.5)) + 1
    return np.arange(n) * dt


def sort_checked(t: np.ndarray, v: np.ndarray, *, path: object, channel: str,
                 time_ordered: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Sort samples by time and reject duplicate timestamps and a clock that jumps back.

    A logger may write a few samples out of order (threads, buffers): those are sorted.
    In a format that writes samples in time order (``time_ordered``), a step back of more
    than :data:`MAX_BACK_S` is a clock reset or two logs joined, and sorting would
    interleave them into one garbage session.

    Raises
    ------
    DataError
        Two samples of the channel share a timestamp (names the count and the first time),
        or the time goes back by more than :data:`MAX_BACK_S` (names where and by how much).
    """
    if t.size > 1 and not (np.diff(t) > 0).all():
        step = np.diff(t)
        k = int(np.argmin(step))
        if time_ordered and step[k] < -MAX_BACK_S:
            raise DataError(
                f"the time goes back by {-float(step[k]):.3f} s after sample {k + 1} (t ="
                f" {float(t[k]):.3f} s from the session start): the logger's clock was reset"
                " or two logs were joined; split the file there and give each part alone",
                path=path, channel=channel)
        order = np.argsort(t, kind="stable")
        t, v = t[order], v[order]
    dup = np.diff(t) == 0
    if dup.any():
        first = float(t[int(np.argmax(dup))])
        raise DataError(
            f"{int(dup.sum())} duplicate timestamp(s), the first at t = {first:.6f} s from the"
            " session start; each sample of a channel needs its own time",
            path=path,
            channel=channel,
        )
    return t, v


def hampel(v: np.ndarray, half_window: int = 4, n_sigma: float = 5.0, floor: float = 5.0
           ) -> tuple[np.ndarray, int]:
    """Replace isolated spikes by the median of their window.

    The noise scale of a sample is the larger of its window's robust standard deviation
    (1.4826 MAD) and the channel's typical one (the median over all windows): a nine-
    sample MAD alone is too noisy an estimate and flags ordinary noise as spikes.

    Parameters
    ----------
    v : ndarray
        Samples at the native rate (degC for IR channels).
    half_window : int
        Samples on each side of the window centre.
    n_sigma : float
        Threshold in noise standard deviations.
    floor : float
        Smallest deviation ever called a spike — same unit as ``v``; keeps sensor
        quantisation on a flat signal (MAD = 0) from being flagged.

    Returns
    -------
    filtered : ndarray
    spikes : int
        Number of samples replaced.
    """
    width = 2 * half_window + 1
    if v.size < width:
        return v, 0
    windows = sliding_window_view(v, width)
    med = np.median(windows, axis=1)
    sigma = _MAD_TO_SIGMA * np.median(np.abs(windows - med[:, None]), axis=1)
    sigma = np.maximum(sigma, np.median(sigma))
    centre = v[half_window : v.size - half_window]
    spike = np.abs(centre - med) > np.maximum(n_sigma * sigma, floor)
    count = int(spike.sum())
    if count == 0:
        return v, 0
    out = v.copy()
    out[half_window : v.size - half_window][spike] = med[spike]
    return out, count


def resample(t: np.ndarray, v: np.ndarray, t_grid: np.ndarray, gap_limit_s: float = 1.0
             ) -> Resampled:
    """Average a sorted, duplicate-free channel into the grid's bins and interpolate.

    Parameters
    ----------
    t : ndarray
        Sample times, s, strictly increasing (see :func:`sort_checked`).
    v : ndarray
        Samples (any unit; returned in the same unit).
    t_grid : ndarray
        The grid of :func:`grid`, s; its spacing sets the bin width (0.1 s for the
        disc pipelines, the rig's own rate for the rig pipelines).
    gap_limit_s : float
        Longest spacing between native samples that is bridged, s. A channel's own
        sample period never counts as a gap: the limit used is at least 1.5 times the
        median spacing, so a 0.5 Hz ambient channel is interpolated, not blanked.

    Returns
    -------
    Resampled
    """
    n = t_grid.size
    dt = float(t_grid[1] - t_grid[0]) if n > 1 else GRID_DT
    if t.size == 0:
        return Resampled(np.full(n, np.nan), (), 0.0)
    spacing = np.diff(t)
    median_dt = float(np.median(spacing)) if spacing.size else 0.0
    rate = 1.0 / median_dt if median_dt > 0 else 0.0
    limit = max(gap_limit_s, 1.5 * median_dt)

    # A sample on a bin edge (t_k + dt/2) goes to the later bin whatever its float
    # round-off, so float-seconds and integer-nanosecond files bin alike.
    k = np.clip(np.floor(t / dt + (0.5 + _EDGE_TOL)).astype(np.int64), 0, n - 1)
    count = np.bincount(k, minlength=n)
    filled = count > 0
    c = count[filled]
    t_mean = np.bincount(k, weights=t, minlength=n)[filled] / c
    v_mean = np.bincount(k, weights=v, minlength=n)[filled] / c
    out = np.interp(t_grid, t_mean, v_mean)
    if t_mean.size >= 2:
        # A half-filled edge bin has its mean time inside the data: extrapolate its slope
        # to the edge grid points (exact for a ramp), clamped at half a bin outside the data.
        lo = t_grid < t_mean[0]
        slope = (v_mean[1] - v_mean[0]) / (t_mean[1] - t_mean[0])
        out[lo] = v_mean[0] + (np.maximum(t_grid[lo], t[0] - 0.5 * dt) - t_mean[0]) * slope
        hi = t_grid > t_mean[-1]
        slope = (v_mean[-1] - v_mean[-2]) / (t_mean[-1] - t_mean[-2])
        out[hi] = v_mean[-1] + (np.minimum(t_grid[hi], t[-1] + 0.5 * dt) - t_mean[-1]) * slope

    # Empty bins are bridged only where the data allow it.
    lead = t[0] > limit
    trail = t_grid[-1] - t[-1] > limit
    outside = ~filled & ((lead & (t_grid < t[0])) | (trail & (t_grid > t[-1])))
    gaps: list[tuple[float, float]] = []
    if lead:
        gaps.append((0.0, float(t[0])))
    long = np.flatnonzero(spacing > limit)
    if long.size:
        gaps.extend((float(t[i]), float(spacing[i])) for i in long)
        nxt = np.searchsorted(t, t_grid, side="right")
        inside = (nxt > 0) & (nxt < t.size)
        span = np.zeros(n)
        span[inside] = t[nxt[inside]] - t[nxt[inside] - 1]
        outside |= (span > limit) & ~filled
    if trail:
        gaps.append((float(t[-1]), float(t_grid[-1] - t[-1])))
    out[outside] = np.nan
    return Resampled(out, tuple(gaps), rate)
