"""The native-rate channel table every reader returns, before aliases, units and resampling."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# Timestamps above this many nanoseconds (about 3 years) are absolute epoch times.
EPOCH_THRESHOLD_NS = 1.0e17
EPOCH_THRESHOLD_S = EPOCH_THRESHOLD_NS * 1e-9


@dataclass(frozen=True)
class RawChannel:
    """One channel as stored in the file.

    Attributes
    ----------
    name : str
        Source name (topic, ``topic.field`` or column).
    t : ndarray
        Sample times, s from the session start (the earliest sample of any channel);
        not necessarily sorted.
    v : ndarray
        Samples in the file's unit (float64).
    unit : str or None
        Unit string from the file, ``None`` when the file gives none.
    """

    name: str
    t: np.ndarray
    v: np.ndarray
    unit: str | None = None


@dataclass(frozen=True)
class RawSession:
    """Everything a reader extracted from one file, at native rates.

    Attributes
    ----------
    path : Path
    channels : tuple of RawChannel
    metadata : dict of str to str
        Session facts.
    origin_s : float or None
        The file's clock reading at ``t = 0`` (the earliest sample), s: an epoch time
        when the file carries absolute time; ``None`` when the file has no clock.
    warnings : tuple of str
    format : str
        Name of the file format (set by the registry, ``"MCAP"``, ``"MDF4"``...).
    """

    path: Path
    channels: tuple[RawChannel, ...]
    metadata: dict[str, str] = field(default_factory=dict)
    origin_s: float | None = None
    warnings: tuple[str, ...] = ()
    format: str = ""

    @property
    def start_epoch_s(self) -> float | None:
        """Epoch time of ``t = 0`` when the file carries absolute time, s."""
        if self.origin_s is not None and self.origin_s > EPOCH_THRESHOLD_S:
            return self.origin_s
        return None

    @property
    def names(self) -> tuple[str, ...]:
        """Source names of all channels, in file order."""
        return tuple(c.name for c in self.channels)

    @property
    def end_s(self) -> float:
        """Time of the last sample of any channel, s."""
        ends = [float(c.t.max()) for c in self.channels if c.t.size]
        return max(ends, default=0.0)


def rebase_ns(times_ns: list[np.ndarray]) -> tuple[list[np.ndarray], float | None]:
    """Shift integer nanosecond timestamps so the earliest of all is 0 and convert to s.

    Returns
    -------
    times_s : list of ndarray
        Float64 seconds from the earliest timestamp.
    origin_s : float or None
        The earliest timestamp, s (an epoch time when the timestamps are absolute).
    """
    starts = [int(t.min()) for t in times_ns if t.size]
    if not starts:
        return [np.asarray(t, dtype=np.float64) for t in times_ns], None
    t0 = min(starts)
    out = [(t.astype(np.int64) - np.int64(t0)).astype(np.float64) * 1e-9 for t in times_ns]
    return out, t0 * 1e-9


# Absolute float times coarser than this (|t| above about 8e6 s: epoch seconds) have
# lost the precision a regular log's steps need; below it nothing is touched.
FLOAT_TIME_RESOLUTION_S = 1e-9


def regular_grid(t: np.ndarray, resolution_s: float) -> np.ndarray:
    """``t`` on the regular grid its samples were logged on, where it is one within the
    float resolution of its absolute times; ``t`` itself otherwise.

    Epoch seconds stored as float64 (1.7e9 s) keep only 2.4e-7 s: a 1 kHz log's steps
    read 0.999928 or 1.000166 ms, its median step gave 1000.07 Hz and the grid's bins
    then held 0 or 2 samples (a tyre's noise_std_mu read 0.0218 for 0.0308). The grid's
    step and offset are fitted by least squares on the sample counts.

    Parameters
    ----------
    t : ndarray
        One channel's times, s, rebased (small values; their error is the absolute's).
    resolution_s : float
        The spacing of the float64 absolute times, s.

    Returns
    -------
    ndarray
        The times, s: snapped where every sample lies within two resolutions of the fitted
        grid (and the step is over 20 resolutions), else unchanged (jitter, gaps off the
        grid, too few samples).
    """
    if t.size < 3 or not np.isfinite(t).all():
        return t
    d = np.diff(t)
    step = float(np.median(d))
    tol = 2.0 * resolution_s
    if not step > 10.0 * tol or (d <= 0.0).any():
        return t
    k = np.round((t - t[0]) / step).astype(np.int64)
    kc = k - k.mean()
    step = float(np.dot(kc, t - t.mean()) / np.dot(kc, kc))
    start = float(t.mean()) - step * float(k.mean())
    # a whole number of nanoseconds first, computed as rebase_ns does: the same session
    # with timestamp[ns] times then reads the same grid to the last bit (samples on a
    # bin's edge fall in the same bin)
    ns = ((round(start * 1e9) + k * round(step * 1e9)).astype(np.float64) * 1e-9)
    for grid in (ns, start + step * k.astype(np.float64)):
        if float(np.max(np.abs(t - grid))) <= tol:
            return grid
    return t


def rebase_s(times_s: list[np.ndarray]) -> tuple[list[np.ndarray], float | None]:
    """Float-seconds counterpart of :func:`rebase_ns`; times of absolute clocks (epoch
    seconds) put back on their logged grid (:func:`regular_grid`)."""
    starts = [float(np.nanmin(t)) for t in times_s if t.size and not np.isnan(t).all()]
    if not starts:
        return list(times_s), None
    t0 = min(starts)
    out = [t - t0 for t in times_s]
    ends = [float(np.nanmax(np.abs(t))) for t in times_s if t.size and not np.isnan(t).all()]
    resolution = float(np.spacing(max(ends)))
    if resolution > FLOAT_TIME_RESOLUTION_S:
        out = [regular_grid(t, resolution) for t in out]
        # the fitted grids may start a fraction of a resolution off zero
        shift = min(float(np.nanmin(t)) for t in out if t.size and not np.isnan(t).all())
        out, t0 = [t - shift for t in out], t0 + shift
    return out, t0


@dataclass(frozen=True)
class Format:
    """One session file format: a reader module registers one of these.

    Attributes
    ----------
    name : str
        Shown to the user (``inspect``), e.g. ``"MDF4"``.
    suffixes : tuple of str
        File extensions, lower case with the dot.
    read : callable
        ``read(path) -> RawSession``: the file at native rates, times in s from the
        earliest sample. Aliases, units, time sanity, gaps, laps and resampling are
        shared (:mod:`brakethermo.io.load`), not the reader's business.
    time_ordered : bool
        The format writes each channel's samples in time order (rows of a table, records
        of a channel group), so a step back in time is a clock reset; False where it may
        legitimately hold them out of order (MCAP's messages).
    """

    name: str
    suffixes: tuple[str, ...]
    read: Callable[[Path], RawSession]
    time_ordered: bool = True
