"""Parquet session reader (CHANNELS.md §1): one wide table, nulls where a channel has no sample."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from brakethermo.errors import DataError
from brakethermo.io.raw import RawChannel, RawSession, rebase_ns, rebase_s


def _session_metadata(schema: pa.Schema, path: Path) -> dict[str, str]:
    raw = (schema.metadata or {}).get(b"session")
    if raw is None:
        return {}
    try:
        facts = json.loads(raw)
    except ValueError:
        raise DataError(
            "key-value metadata 'session' is not valid JSON; it must be a JSON object",
            path=path,
        ) from None
    if not isinstance(facts, dict):
        raise DataError("key-value metadata 'session' must be a JSON object", path=path)
    return {str(k): v if isinstance(v, str) else json.dumps(v) for k, v in facts.items()}


def _time_seconds(column: pa.ChunkedArray, path: Path) -> tuple[np.ndarray, float | None]:
    """The ``time`` column as seconds from its earliest value, and the epoch start if any."""
    if column.null_count:
        raise DataError("column 'time' has empty cells; every row needs a time", path=path)
    kind = column.type
    if pa.types.is_timestamp(kind) or pa.types.is_duration(kind):
        ns = pc.cast(column, pa.timestamp("ns") if pa.types.is_timestamp(kind)
                     else pa.duration("ns"))
        (t,), epoch = rebase_ns([ns.to_numpy().view(np.int64)])
        return t, epoch
    if pa.types.is_integer(kind) or pa.types.is_floating(kind):
        (t,), epoch = rebase_s([column.to_numpy().astype(np.float64)])
        return t, epoch
    raise DataError(
        f"column 'time' has type {kind}; it must be float seconds or timestamp[ns]", path=path
    )


def _numeric(column: pa.ChunkedArray, name: str, path: Path) -> np.ndarray | None:
    """A column as float64 with NaN for nulls.

    Text is parsed; a column of text only (or of a non-numeric type) is not a channel
    and gives ``None``; a column mixing numbers and text is an error naming the row.
    """
    kind = column.type
    if pa.types.is_string(kind) or pa.types.is_large_string(kind):
        try:
            column = pc.cast(column, pa.float64())
        except pa.ArrowInvalid:
            cells = column.to_pylist()
            numbers = pd.to_numeric(pd.Series(cells, dtype=object), errors="coerce")
            bad = numbers.isna().to_numpy() & np.array([c is not None for c in cells])
            if numbers.isna().all():
                return None
            row = int(np.argmax(bad))
            raise DataError(
                f"non-numeric value {cells[row]!r} in row {row + 1}; every sample must be"
                " a number or null",
                path=path,
                channel=name,
            ) from None
    elif not (pa.types.is_integer(kind) or pa.types.is_floating(kind)
              or pa.types.is_boolean(kind)):
        return None
    return pc.cast(column, pa.float64()).to_numpy(zero_copy_only=False)


def read_parquet(path: Path) -> RawSession:
    """Read a wide Parquet session table into native-rate channels.

    Parameters
    ----------
    path : Path
        The ``.parquet`` file: column ``time`` (float64 s or ``timestamp[ns]``) and one
        column per channel, null where the channel has no sample.

    Returns
    -------
    RawSession
        One channel per column (nulls dropped), units from the field metadata key
        ``unit``, session facts from the key-value metadata ``session``.

    Raises
    ------
    DataError
        Not a Parquet file, no ``time`` column, a column mixing numbers and text (a
        column that is not numeric at all is skipped with a warning).
    """
    try:
        table = pq.read_table(path)
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"not a readable Parquet file ({exc})", path=path) from None
    if "time" not in table.column_names:
        raise DataError(
            f"no 'time' column; the columns are: {', '.join(table.column_names) or 'none'}",
            path=path,
        )
    t, epoch = _time_seconds(table.column("time"), path)
    channels = []
    warnings = []
    for fld in table.schema:
        if fld.name == "time":
            continue
        v = _numeric(table.column(fld.name), fld.name, path)
        if v is None:
            warnings.append(f"column '{fld.name}' ({fld.type}) is not numeric; ignored")
            continue
        keep = ~np.isnan(v)
        unit = (fld.metadata or {}).get(b"unit")
        channels.append(
            RawChannel(fld.name, t[keep], v[keep], unit.decode() if unit is not None else None)
        )
    return RawSession(path, tuple(channels), _session_metadata(table.schema, path), epoch,
                      tuple(warnings))
