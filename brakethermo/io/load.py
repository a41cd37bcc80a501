"""``load_session``: any session file of CHANNELS.md -> one :class:`Session` on a uniform grid.

The disc pipelines take the 10 Hz grid of OUTPUTS.md (the default); the rig pipelines
pass their own ``rate_hz`` (or ``None``: the fastest native rate of the channels they
use). One reader stack serves both.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from brakethermo.errors import DataError
from brakethermo.io.aliases import AliasTable, load_aliases, resolve
from brakethermo.io.csv_reader import read_csv
from brakethermo.io.laps import laps_from_beacons
from brakethermo.io.mcap_reader import read_mcap
from brakethermo.io.parquet_reader import read_parquet
from brakethermo.io.raw import RawChannel, RawSession
from brakethermo.io.resample import grid, hampel, resample, sort_checked
from brakethermo.io.session import GRID_DT, ChannelInfo, Session
from brakethermo.io.units import CANONICAL_CHANNELS, si_unit, to_si

READERS: dict[str, Callable[[Path], RawSession]] = {
    ".mcap": read_mcap,
    ".parquet": read_parquet,
    ".csv": read_csv,
}

# Channels whose isolated spikes are rejected (IR pyrometer readings).
IR_PREFIX = "disc_temp"


def read_raw(path: str | Path) -> RawSession:
    """Read a session file at native rates, dispatching on the extension.

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
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        raise DataError(
            f"unknown session file type '{path.suffix}'; expected one of "
            + ", ".join(READERS),
            path=path,
        )
    if path.stat().st_size == 0:
        raise DataError("the file is empty (0 bytes)", path=path)
    return reader(path)


def _finite(ch: RawChannel) -> tuple[np.ndarray, np.ndarray]:
    keep = np.isfinite(ch.v) & np.isfinite(ch.t)
    if keep.all():
        return ch.t, ch.v
    return ch.t[keep], ch.v[keep]


def load_session(
    path: str | Path,
    *,
    aliases: str | Path | Mapping[str, tuple[str, ...]] | None = None,
    gap_limit_s: float = 1.0,
    rate_hz: float | None = 1.0 / GRID_DT,
    channels: tuple[str, ...] | None = None,
) -> Session:
    """Load a session file onto a uniform grid with canonical names and SI units.

    Parameters
    ----------
    path : str or Path
        ``.mcap``, ``.parquet`` or ``.csv`` session file (extension case-insensitive).
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

    Returns
    -------
    Session
        Only channels that map to canonical names are in :attr:`Session.frame`; every
        source name is in :attr:`Session.available`. A channel with a single finite
        sample goes to :attr:`Session.constants` instead of the frame.

    Raises
    ------
    DataError
        Unreadable input, unknown units, non-numeric values, duplicate timestamps.
    ConfigError
        An invalid alias file.
    """
    if gap_limit_s <= 0:
        raise DataError(f"gap limit must be positive, got {gap_limit_s} s")
    table: AliasTable = (
        {k: tuple(v) for k, v in aliases.items()}
        if isinstance(aliases, Mapping)
        else load_aliases(aliases)
    )
    raw = read_raw(path)
    path = raw.path
    by_name = {c.name: c for c in raw.channels}
    found = resolve(table, raw.names)
    if not any(c.t.size for c in raw.channels):
        raise DataError("the file holds no samples", path=path)
    wanted = CANONICAL_CHANNELS if channels is None else channels
    series: dict[str, tuple[RawChannel, np.ndarray, np.ndarray, str]] = {}
    constants: dict[str, float] = {}
    for canonical in wanted:
        if canonical not in found or canonical == "lap_beacon":
            continue
        src = by_name[found[canonical]]
        t, v = sort_checked(*_finite(src), path=path, channel=src.name)
        v, unit = to_si(v, src.unit, canonical, path=path, source=src.name)
        if t.size == 1:
            constants[canonical] = float(v[0])
        else:
            series[canonical] = (src, t, v, unit)
    if rate_hz is None:
        rates = [1.0 / float(np.median(np.diff(t))) for _, t, _, _ in series.values()
                 if t.size > 1]
        rate_hz = max(rates, default=1.0 / GRID_DT)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise DataError(f"grid rate must be a positive number of Hz, got {rate_hz}", path=path)
    dt = 1.0 / rate_hz
    t_grid = grid(raw.end_s, dt)

    columns: dict[str, np.ndarray] = {"time": t_grid}
    infos: dict[str, ChannelInfo] = {}
    warnings = list(raw.warnings)
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
            warnings.append(
                f"channel '{canonical}' ({src.name}): {len(res.gaps)} gap(s) longer than"
                f" {gap_limit_s:g} s left empty, {total:.1f} s in total"
            )

    if "lap_beacon" in found:
        src = by_name[found["lap_beacon"]]
        tb, vb = sort_checked(*_finite(src), path=path, channel=src.name)
        laps, lap = laps_from_beacons(tb, vb, t_grid, raw.end_s, path=path, channel=src.name)
    else:
        laps, lap = laps_from_beacons(np.empty(0), np.empty(0), t_grid, raw.end_s, path=path)
    frame = pd.DataFrame({"time": columns.pop("time"), "lap": lap, **columns})
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
    )
