"""``load_session``: any session file -> one :class:`Session` on a uniform grid.

Each format is one reader module registered in :mod:`brakethermo.io.formats`; it only
turns the file into native-rate channels (:class:`RawSession`). Everything else is
done here once for all formats: time sanity (clock jumps, impossible spans), aliases,
units, non-finite samples, unusable channels, spikes, gaps, beacon checks, laps and
resampling.

The disc pipelines take the 10 Hz grid of OUTPUTS.md (the default); the rig pipelines
pass their own ``rate_hz`` (or ``None``: the fastest native rate of the channels they
use). One reader stack serves both.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from brakethermo.errors import DataError
from brakethermo.io import csv_reader
from brakethermo.io.aliases import AliasTable, load_aliases, resolve
from brakethermo.io.formats import BY_SUFFIX, FORMATS
from brakethermo.io.laps import (
    beacons_from_distance,
    lap_length_warnings,
    laps_from_beacons,
    mark_cut_end,
    validate_beacons,
)
from brakethermo.io.raw import RawChannel, RawSession
from brakethermo.io.resample import grid, hampel, resample, sort_checked
from brakethermo.io.session import GRID_DT, ChannelInfo, Lap, Session
from brakethermo.io.timebase import settle
from brakethermo.io.units import CANONICAL_CHANNELS, si_unit, to_si

# Most grid points a session may plan (about 0.8 GB per channel): beyond it the rate or
# the time stamps are wrong, and the user is told before anything is allocated.
MAX_GRID_POINTS = 100_000_000

# Channels whose isolated spikes are rejected (IR pyrometer readings).
IR_PREFIX = "disc_temp"


def read_raw(path: str | Path, indexed: bool = False) -> RawSession:
    """Read a session file at native rates, dispatching on the extension.

    ``indexed``: a CSV is a table of points, not a time series (every column a channel,
    row ``i`` at ``i`` s); the other formats carry their own time axis either way.

    The times are settled (:func:`brakethermo.io.timebase.settle`): isolated samples
    far outside the session dropped with a warning, an implausible span refused.

    Raises
    ------
    DataError
        Missing file, a directory, an empty file or an unknown extension, or whatever
        the format's reader rejects.
    """
    path = Path(path)
    if not path.exists():
        raise DataError("file not found; check the path", path=path)
    if not path.is_file():
        raise DataError("is not a file; give one session file (batch reads folders)", path=path)
    fmt = BY_SUFFIX.get(path.suffix.lower())
    if fmt is None:
        raise DataError(
            f"unknown session file type '{path.suffix}'; expected one of "
            + ", ".join(BY_SUFFIX),
            path=path,
        )
    if path.stat().st_size == 0:
        raise DataError("the file is empty (0 bytes)", path=path)
    raw = csv_reader.read_csv(path, indexed=True) if indexed and fmt is csv_reader.FORMAT \
        else fmt.read(path)
    return settle(dataclasses.replace(raw, format=raw.format or fmt.name))


def _finite(ch: RawChannel) -> tuple[np.ndarray, np.ndarray, int]:
    keep = np.isfinite(ch.v) & np.isfinite(ch.t)
    if keep.all():
        return ch.t, ch.v, 0
    return ch.t[keep], ch.v[keep], int((~keep).sum())


# A pause in a log longer than this and than half the span is two recordings in one file.
MAX_PAUSE_S = 6 * 3600.0


def _refuse_split_session(series: dict, end_s: float, path: Path) -> None:
    """Refuse a file whose samples leave most of its span empty (two sessions, days apart)."""
    times = [t for _, t, _, _ in series.values() if t.size]
    if not times or end_s <= MAX_PAUSE_S:
        return
    merged = np.unique(np.concatenate(times))
    pause = np.diff(merged)
    k = int(np.argmax(pause))
    if pause[k] > MAX_PAUSE_S and pause[k] > 0.5 * end_s:
        raise DataError(
            f"the log has a pause of {pause[k] / 86400.0:.2f} days (from t = {merged[k]:.1f} s"
            f" to {merged[k + 1]:.1f} s) in a span of {end_s / 86400.0:.2f} days: the file "
            "holds two recordings; split it into one file per session", path=path)


_Series = dict[str, tuple[RawChannel, np.ndarray, np.ndarray, str]]


def time_ordered(raw: RawSession) -> bool:
    """Whether the file's format writes samples in time order (:class:`Format`)."""
    return next((f.time_ordered for f in FORMATS if f.name == raw.format), True)


def _gather(raw: RawSession, found: dict[str, str], wanted: tuple[str, ...],
            warnings: list[str]) -> tuple[_Series, dict[str, float], dict[str, str]]:
    """The wanted channels in SI, finite, sorted: series, single-sample constants and
    the unusable ones with why (warnings appended)."""
    path = raw.path
    by_name = {c.name: c for c in raw.channels}
    ordered = time_ordered(raw)
    series: _Series = {}
    constants: dict[str, float] = {}
    unusable: dict[str, str] = {}
    for canonical in wanted:
        if canonical not in found or canonical == "lap_beacon":
            continue
        src = by_name[found[canonical]]
        t, v, n_bad = _finite(src)
        v, unit = to_si(v, src.unit, canonical, path=path, source=src.name)
        if t.size == 0:
            unusable[canonical] = (
                f"'{src.name}' holds no finite sample"
                + (f" (all {n_bad} are null, NaN or infinite)" if n_bad else " (it is empty)")
            )
            continue
        if n_bad:
            warnings.append(
                f"channel '{canonical}' ({src.name}): {n_bad} non-finite sample(s) (NaN or"
                " infinite) dropped"
            )
        t, v = sort_checked(t, v, path=path, channel=src.name, time_ordered=ordered)
        if t.size == 1:
            constants[canonical] = float(v[0])
        else:
            series[canonical] = (src, t, v, unit)
    return series, constants, unusable


def _grid_step(series: _Series, end_s: float, rate_hz: float | None, path: Path) -> float:
    """The grid step, s: from ``rate_hz``, else the fastest channel that covers at least
    half the session; refused when the grid would not fit."""
    if rate_hz is None:
        # A short burst (a validation channel logged at 100 kHz for 0.1 s) must not set
        # the grid of the whole session: only channels covering half the span count.
        long = [t for _, t, _, _ in series.values()
                if t.size > 1 and t[-1] - t[0] >= 0.5 * end_s]
        rates = [1.0 / float(np.median(np.diff(t))) for t in long]
        rate_hz = max(rates, default=1.0 / GRID_DT)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise DataError(f"grid rate must be a positive number of Hz, got {rate_hz}", path=path)
    dt = 1.0 / rate_hz
    points = end_s * rate_hz
    if points > MAX_GRID_POINTS:
        raise DataError(
            f"the session spans {end_s:.1f} s: at {rate_hz:g} Hz that is {points:.3g} grid"
            f" points, more than {MAX_GRID_POINTS:.0e}; check the time stamps or use a lower"
            " grid rate",
            path=path,
        )
    return dt


def _on_grid(series: _Series, t_grid: np.ndarray, gap_limit_s: float, warnings: list[str]
             ) -> tuple[dict[str, np.ndarray], dict[str, ChannelInfo]]:
    """Each series despiked (pyrometers) and resampled onto ``t_grid``, with its facts."""
    columns: dict[str, np.ndarray] = {}
    infos: dict[str, ChannelInfo] = {}
    for canonical, (src, t, v, unit) in series.items():
        spikes = 0
        if canonical.startswith(IR_PREFIX):
            v, spikes = hampel(v)
        res = resample(t, v, t_grid, gap_limit_s)
        columns[canonical] = res.values
        infos[canonical] = ChannelInfo(
            canonical, src.name, unit, si_unit(canonical), res.rate_hz, int(t.size),
            res.gaps, spikes,
        )
        if res.gaps:
            total = sum(d for _, d in res.gaps)
            start, longest = max(res.gaps, key=lambda g: g[1])
            warnings.append(
                f"channel '{canonical}' ({src.name}): {len(res.gaps)} gap(s) longer than"
                f" {gap_limit_s:g} s left empty, {total:.1f} s in total (the longest"
                f" {longest:.1f} s from t = {start:.1f} s)"
            )
    return columns, infos


def _alias_table(aliases: str | Path | Mapping[str, tuple[str, ...]] | None) -> AliasTable:
    """The alias table: a ready mapping as given, else the shipped table merged with the
    user's alias file, if any (:func:`load_aliases`)."""
    return (
        {k: tuple(v) for k, v in aliases.items()}
        if isinstance(aliases, Mapping)
        else load_aliases(aliases)
    )


def _laps(raw: RawSession, found: dict[str, str], t_grid: np.ndarray, warnings: list[str]
          ) -> tuple[tuple[Lap, ...], np.ndarray]:
    """The laps and the lap of every grid time, from the beacon channel if the file
    maps one (its notes appended to ``warnings``), else the whole session as lap 0."""
    path = raw.path
    if "lap_beacon" not in found:
        resets = np.empty(0)
        if "distance" in found:
            dist = {c.name: c for c in raw.channels}[found["distance"]]
            td, vd, _ = _finite(dist)
            resets = beacons_from_distance(*sort_checked(
                td, vd, path=path, channel=dist.name, time_ordered=time_ordered(raw)))
        if resets.size == 0:
            return laps_from_beacons(np.empty(0), np.empty(0), t_grid, raw.end_s, path=path)
        warnings.append(f"no lap_beacon channel: {resets.size} line crossing(s) taken where"
                        f" {dist.name} goes back to 0; log the beacon to be sure of the laps")
        laps, lap = laps_from_beacons(resets, np.arange(1.0, resets.size + 1.0), t_grid,
                                      raw.end_s, path=path, channel=dist.name)
        warnings.extend(lap_length_warnings(laps, dist.name))
        return laps, lap
    src = {c.name: c for c in raw.channels}[found["lap_beacon"]]
    tb, vb, _ = _finite(src)
    tb, vb = sort_checked(tb, vb, path=path, channel=src.name,
                          time_ordered=time_ordered(raw))
    tb, vb, notes = validate_beacons(tb, vb, path=path, channel=src.name)
    warnings.extend(notes)
    laps, lap = laps_from_beacons(tb, vb, t_grid, raw.end_s, path=path, channel=src.name)
    warnings.extend(lap_length_warnings(laps, src.name))
    return laps, lap


def load_session(
    path: str | Path,
    *,
    aliases: str | Path | Mapping[str, tuple[str, ...]] | None = None,
    gap_limit_s: float = 1.0,
    rate_hz: float | None = 1.0 / GRID_DT,
    channels: tuple[str, ...] | None = None,
    indexed: bool = False,
) -> Session:
    """Load a session file onto a uniform grid with canonical names and SI units.

    Parameters
    ----------
    path : str or Path
        Session file of any registered format (``.mcap``, ``.parquet``, ``.csv``,
        ``.mf4``/``.mdf``, ``.xrk``/``.xrz``; extension case-insensitive).
    aliases : str, Path or mapping, optional
        A user alias TOML file merged over the shipped table, or a ready alias table.
    gap_limit_s : float
        Longest gap between native samples bridged by interpolation, s; longer gaps
        stay NaN and are reported in :attr:`ChannelInfo.gaps`.
    rate_hz : float or None
        Grid rate, Hz: 10 (the OUTPUTS.md disc grid) by default; ``None`` takes the
        fastest native rate among the loaded channels (rig logs).
    channels : tuple of str, optional
        Canonical channels to load (default: every canonical channel the file maps);
        a rig pipeline names its own so that unrelated channels cost nothing.
    indexed : bool
        The file is a table of points, not a time series (:func:`read_raw`).

    Returns
    -------
    Session
        Only channels that map to canonical names are in :attr:`Session.frame`; every
        source name is in :attr:`Session.available`. A channel with a single finite
        sample goes to :attr:`Session.constants` instead of the frame, one with none to
        :attr:`Session.unusable`.

    Raises
    ------
    DataError
        Unreadable input, unknown units, non-numeric values, duplicate timestamps.
    ConfigError
        An invalid alias file.
    """
    if not (math.isfinite(gap_limit_s) and gap_limit_s > 0):
        raise DataError(f"gap limit must be a finite number of seconds > 0, got {gap_limit_s}")
    table = _alias_table(aliases)
    raw = read_raw(path, indexed)
    path = raw.path
    found = resolve(table, raw.names)
    if not any(c.t.size for c in raw.channels):
        raise DataError("the file holds no samples", path=path)
    warnings = list(raw.warnings)
    wanted = CANONICAL_CHANNELS if channels is None else channels
    series, constants, unusable = _gather(raw, found, wanted, warnings)
    _refuse_split_session(series, raw.end_s, path)
    dt = _grid_step(series, raw.end_s, rate_hz, path)
    t_grid = grid(raw.end_s, dt)

    columns, infos = _on_grid(series, t_grid, gap_limit_s, warnings)
    laps, lap = _laps(raw, found, t_grid, warnings)
    laps = mark_cut_end(laps, lap, columns.get("speed"), dt)
    frame = pd.DataFrame({"time": t_grid, "lap": lap, **columns})
    return Session(
        path=path,
        frame=frame,
        channels=infos,
        laps=laps,
        metadata=dict(raw.metadata),
        aliases=dict(table),
        available=raw.names,
        start_epoch_s=raw.start_epoch_s,
        warnings=tuple(warnings),
        dt=dt,
        constants=constants,
        format=raw.format,
        unusable=unusable,
    )
