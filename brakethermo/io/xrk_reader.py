"""AiM XRK / XRZ reader through ``libxrk`` (an optional dependency: ``brakethermo[xrk]``).

Channels keep their AiM names and units (``units`` in the channel's field metadata);
times are the logger's millisecond time codes. The laps come from the file's own lap
table: each lap's start becomes a ``lap_beacon`` sample with the lap's number (libxrk
numbers laps from 0, the out-lap), so the shared beacon checks apply to them too.
Session facts: ``vehicle``, ``track`` (AiM venue), ``driver``, ``date``...
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from brakethermo.errors import DataError
from brakethermo.io.raw import Format, RawChannel, RawSession, rebase_ns

BEACON = "lap_beacon"
_FACTS = {
    "Vehicle": "vehicle", "Venue": "track", "Driver": "driver", "Log Date": "date",
    "Log Time": "time", "Session": "session", "Series": "series",
    "Long Comment": "comment", "Logger Model": "logger",
}  # fmt: skip
_DATE_FORMATS = ("%d/%m/%Y %H:%M:%S", "%m/%d/%Y %H:%M:%S", "%Y-%m-%d %H:%M:%S")


def _loader(path: Path) -> Any:
    try:
        from libxrk import aim_xrk
    except ImportError as exc:
        raise DataError(
            "reading AiM XRK/XRZ files needs the optional package libxrk, which is not"
            f" installed or does not load on this platform ({exc}). Install it with"
            " pip install 'brakethermo[xrk]', or export the session from Race Studio as"
            " CSV; the other formats work without it",
            path=path,
        ) from None
    return aim_xrk


def _epoch(meta: dict[str, Any]) -> float | None:
    text = f"{meta.get('Log Date', '')} {meta.get('Log Time', '')}".strip()
    for fmt in _DATE_FORMATS:
        try:
            return dt.datetime.strptime(text, fmt).replace(tzinfo=dt.UTC).timestamp()
        except ValueError:
            continue
    return None


def read_xrk(path: Path) -> RawSession:
    """Read an AiM XRK/XRZ file into native-rate channels and lap beacons.

    Raises
    ------
    DataError
        libxrk missing, a file libxrk cannot parse, or a file without channels.
    """
    aim_xrk = _loader(path)
    try:
        log = aim_xrk(str(path))
    except Exception as exc:  # the parser raises assorted errors on damaged files
        raise DataError(
            f"not a readable AiM XRK/XRZ file ({type(exc).__name__}: {str(exc)[:160]}); check"
            " that it is an AiM log and not truncated or damaged",
            path=path,
        ) from None
    names: list[str] = []
    ticks: list[np.ndarray] = []
    values: list[np.ndarray] = []
    units: list[str | None] = []
    warnings: list[str] = []
    for name, table in log.channels.items():
        field = table.schema.field(name)
        column = table.column(name)
        kind = column.type
        if not (pa.types.is_integer(kind) or pa.types.is_floating(kind)
                or pa.types.is_boolean(kind)):
            warnings.append(f"channel '{name}' ({kind}) is not numeric; ignored")
            continue
        unit = (field.metadata or {}).get(b"units", b"").decode(errors="replace").strip()
        names.append(str(name))
        ticks.append(table.column("timecodes").to_numpy().astype(np.int64) * 1_000_000)
        values.append(column.to_numpy(zero_copy_only=False).astype(np.float64))
        units.append(unit or None)
    if log.laps is not None and log.laps.num_rows and BEACON not in names:
        laps = log.laps.to_pydict()
        names.append(BEACON)
        ticks.append(np.asarray(laps["start_time"], dtype=np.int64) * 1_000_000)
        values.append(np.asarray(laps["num"], dtype=np.float64))
        units.append(None)
    if not names:
        raise DataError(
            "libxrk found no channel in the file: it is empty, damaged or not an AiM"
            " XRK/XRZ log",
            path=path,
        )
    times_s, origin_ns_s = rebase_ns(ticks)
    epoch = _epoch(log.metadata or {})
    origin = None if epoch is None else epoch + (origin_ns_s or 0.0)
    facts = {
        _FACTS.get(str(k), str(k)): str(v)
        for k, v in (log.metadata or {}).items()
        if isinstance(v, str | int | float) and str(v).strip()
    }
    channels = tuple(
        RawChannel(n, t, v, u) for n, t, v, u in zip(names, times_s, values, units, strict=True)
    )
    return RawSession(path, channels, facts, origin, tuple(warnings), "AiM XRK")


FORMAT = Format("AiM XRK", (".xrk", ".xrz"), read_xrk)
