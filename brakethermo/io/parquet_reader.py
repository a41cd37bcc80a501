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
from brakethermo.io.raw import Format, RawChannel, RawSession, rebase_ns, rebase_s
from brakethermo.io.timebase import TIME_SCALE, integer_time_scale


def _session_metadata(schema: pa.Schema, path: Path) -> dict[str, str]:
    raw = (schema.metadata or {}).get(b"session")
    if raw is None:
        return {}
    try:
        facts = json.loads(raw)
    except (ValueError, RecursionError):
        raise DataError(
            "key-value metadata 'session' is not valid JSON (or nested too deeply); it must be"
            " a flat JSON object",
            path=path,
        ) from None
    if not isinstance(facts, dict):
        raise DataError("key-value metadata 'session' must be a JSON object", path=path)
    return {str(k): v if isinstance(v, str) else json.dumps(v) for k, v in facts.items()}


def _time_seconds(column: pa.ChunkedArray, unit: str | None, path: Path
                  ) -> tuple[np.ndarray, float | None, str | None]:
    """The ``time`` column as seconds from its earliest value, the clock origin, a note.

    Timestamps and durations carry their unit; a number column takes the field's
    ``unit`` metadata (s, ms, us, ns), else seconds for floats, else (integers) the unit
    inferred from the span and step, said in the note.
    """
    if column.null_count:
        raise DataError("column 'time' has empty cells; every row needs a time", path=path)
    kind = column.type
    if pa.types.is_timestamp(kind) or pa.types.is_duration(kind):
        ns = pc.cast(column, pa.timestamp("ns") if pa.types.is_timestamp(kind)
                     else pa.duration("ns"))
        (t,), origin = rebase_ns([ns.to_numpy().view(np.int64)])
        return t, origin, None
    if pa.types.is_integer(kind) or pa.types.is_floating(kind):
        values = column.to_numpy()
        note = None
        if unit is not None and unit.strip():
            if unit.strip() not in TIME_SCALE:
                raise DataError(
                    f"column 'time' has unit '{unit}'; use s, ms, us or ns", path=path
                )
            scale = TIME_SCALE[unit.strip()]
        elif pa.types.is_integer(kind):
            scale, note = integer_time_scale(values, path=path, column="time")
        else:
            scale = 1.0
        if scale == 1.0:
            (t,), origin = rebase_s([values.astype(np.float64)])
        else:
            # Rebase in integers first: epoch nanoseconds do not fit a float exactly.
            base = values.min()
            (t,), _ = rebase_s([(values - base).astype(np.float64) * scale])
            origin = float(base) * scale
        return t, origin, note
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


def _read_table(path: Path) -> tuple[pa.Table, list[str]]:
    """The whole table, or its intact row groups with a warning for each damaged one.

    Page checksums are verified where the writer stored them.
    """
    try:
        return pq.read_table(path, page_checksum_verification=True), []
    except (pa.ArrowException, OSError) as exc:
        whole_error = exc
    try:
        pf = pq.ParquetFile(path, page_checksum_verification=True)
    except (pa.ArrowException, OSError):
        raise DataError(f"not a readable Parquet file ({whole_error})", path=path) from None
    groups, warnings = [], []
    n = pf.metadata.num_row_groups
    row = 0
    for k in range(n):
        rows = pf.metadata.row_group(k).num_rows
        try:
            groups.append(pf.read_row_group(k))
        except (pa.ArrowException, OSError) as exc:
            warnings.append(
                f"corrupt row group {k + 1} of {n} (rows {row + 1}-{row + rows}): skipped,"
                f" its samples are lost ({str(exc)[:120]})"
            )
        row += rows
    if not groups:
        raise DataError(f"not a readable Parquet file ({whole_error})", path=path) from None
    return pa.concat_tables(groups), warnings


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
    table, warnings = _read_table(path)
    names = table.column_names
    doubled = sorted({n for n in names if names.count(n) > 1})
    if doubled:
        raise DataError(
            f"column{'s' if len(doubled) > 1 else ''} {', '.join(map(repr, doubled))} "
            "appear more than once; rename or drop the copies in the export", path=path)
    if "time" not in table.column_names:
        raise DataError(
            f"no 'time' column; the columns are: {', '.join(table.column_names) or 'none'}",
            path=path,
        )
    time_meta = (table.schema.field("time").metadata or {}).get(b"unit")
    t, epoch, note = _time_seconds(
        table.column("time"), time_meta.decode() if time_meta else None, path
    )
    if note:
        warnings.append(note)
    channels = []
    for fld in table.schema:
        if fld.name == "time":
            continue
        v = _numeric(table.column(fld.name), fld.name, path)
        if v is None:
            warnings.append(f"column '{fld.name}' ({fld.type}) is not numeric; ignored")
            continue
        keep = ~np.isnan(v)
        unit = (fld.metadata or {}).get(b"unit")
        try:
            text = unit.decode() if unit is not None else None
        except UnicodeDecodeError:
            raise DataError(f"the unit of column '{fld.name}' is not UTF-8 text ({unit[:40]!r});"
                            " write it as a unit string of CHANNELS.md §4", path=path) from None
        channels.append(RawChannel(fld.name, t[keep], v[keep], text))
    return RawSession(path, tuple(channels), _session_metadata(table.schema, path), epoch,
                      tuple(warnings))


FORMAT = Format("Parquet", (".parquet",), read_parquet)
