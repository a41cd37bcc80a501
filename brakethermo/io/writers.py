"""Session writers: MCAP, Parquet and CSV exactly as in CHANNELS.md.

A session to write is a set of :class:`Channel` (each with its own timestamps and a
unit string) plus the session facts. Every writer is atomic and byte-deterministic:
the same input gives the same bytes (no wall-clock fields anywhere).
"""

from __future__ import annotations

import io
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from brakethermo.errors import ConfigError
from brakethermo.io.atomic import atomic_path, write_bytes_atomic

if TYPE_CHECKING:  # imported where used: mcap is not loaded by commands that write no MCAP
    from mcap.writer import Writer

FORMATS = ("mcap", "parquet", "csv")
_SCHEMA_VALUE = {"type": "object", "properties": {"value": {"type": "number"}}}


@dataclass(frozen=True)
class Channel:
    """One logged channel.

    Attributes
    ----------
    name : str
        Channel name as written (topic / column).
    unit : str
        Unit string of CHANNELS.md §4 (``""`` for unitless, e.g. ``lap_beacon``).
    time : ndarray — s from the session start, increasing
    value : ndarray
        Samples; NaN marks a missing sample (not written in MCAP, null in Parquet,
        empty in CSV).
    decimals : int
        Digits after the decimal point kept when writing text (CSV, MCAP JSON).
    """

    name: str
    unit: str
    time: np.ndarray
    value: np.ndarray
    decimals: int = 3


@dataclass(frozen=True)
class SessionData:
    """Channels and session facts (``vehicle``, ``track``, ``date``, ``disc``, ...)."""

    channels: tuple[Channel, ...]
    facts: Mapping[str, str] = field(default_factory=dict)


def infer_format(path: str | Path, fmt: str | None = None) -> str:
    """The output format: ``fmt`` if given, else from the file extension."""
    ext = Path(path).suffix.lower().lstrip(".")
    if fmt:
        if fmt not in FORMATS:
            raise ConfigError(f"unknown format '{fmt}'; use one of {', '.join(FORMATS)}")
        if ext in FORMATS and ext != fmt:
            raise ConfigError(f"--format {fmt} for a file named .{ext}: the readers go by the"
                              f" extension; name it .{fmt} or drop --format", path=path)
        return fmt
    if ext not in FORMATS:
        raise ConfigError(
            f"cannot infer the format from the extension '.{ext}'; use .mcap, .parquet or"
            " .csv, or pass --format",
            path=path,
        )
    return ext


def write_session(
    path: str | Path,
    data: SessionData,
    fmt: str | None = None,
    *,
    compression: str = "zstd",
    groups: Mapping[str, Mapping[str, str]] | None = None,
) -> Path:
    """Write a session atomically in MCAP, Parquet or CSV.

    Parameters
    ----------
    path : str or Path
    data : SessionData
    fmt : {"mcap", "parquet", "csv"}, optional
        Inferred from the extension when omitted.
    compression : {"zstd", "lz4", "none"}
        MCAP chunk / Parquet page compression.
    groups : mapping, optional
        MCAP only: grouped topics, ``{topic: {field: channel name}}``; the channels of
        a group must share their timestamps (e.g. ``{"disc_temp": {"spot1":
        "disc_temp_spot1", ...}}``).
    """
    path = Path(path)
    fmt = infer_format(path, fmt)
    if fmt == "mcap":
        write_bytes_atomic(path, mcap_bytes(data, compression=compression, groups=groups))
    elif fmt == "parquet":
        with atomic_path(path) as tmp:
            _write_parquet(wide_table(data), tmp, compression)
    else:
        write_bytes_atomic(path, csv_bytes(data))
    return path


def _fmt(x: float, decimals: int) -> str:
    return f"{x:.{decimals}f}"


def mcap_bytes(
    data: SessionData,
    *,
    compression: str = "zstd",
    groups: Mapping[str, Mapping[str, str]] | None = None,
) -> bytes:
    """The session as MCAP: JSON messages, jsonschema schemas, unit in channel metadata."""
    from mcap.writer import CompressionType, IndexType, Writer

    comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[
        compression
    ]
    by_name = {c.name: c for c in data.channels}
    grouped = {ch for g in (groups or {}).values() for ch in g.values()}
    missing = sorted(grouped - by_name.keys())
    if missing:
        raise ConfigError(f"grouped channels not in the session: {', '.join(missing)}")

    buf = io.BytesIO()
    # Chunk indexes only: per-message indexes would double the file (they are optional).
    writer = Writer(
        buf,
        compression=comp,
        chunk_size=4 << 20,
        index_types=IndexType.CHUNK | IndexType.METADATA | IndexType.ATTACHMENT,
    )
    writer.start(profile="", library="brakethermo")
    writer.add_metadata("session", {str(k): str(v) for k, v in data.facts.items()})
    events: list[tuple[int, int, int, bytes]] = []  # (log_time, channel order, seq, payload)
    order = _channel_events(writer, data.channels, grouped, events)
    _group_events(writer, groups or {}, by_name, order, events)

    events.sort(key=lambda e: (e[0], e[1]))
    seq: dict[int, int] = {}
    for t, _, cid, payload in events:
        seq[cid] = seq.get(cid, 0) + 1
        writer.add_message(cid, log_time=t, data=payload, publish_time=t, sequence=seq[cid])
    writer.finish()
    return buf.getvalue()


def _channel_events(
    writer: Writer, channels: Sequence[Channel], grouped: set[str],
    events: list[tuple[int, int, int, bytes]],
) -> int:
    """Register one topic per channel not in a group and append its messages to
    ``events`` as (log time ns, topic order, channel id, JSON payload); returns the order
    of the next topic."""
    order = 0
    for ch in channels:
        if ch.name in grouped:
            continue
        schema = writer.register_schema(
            name=ch.name, encoding="jsonschema", data=json.dumps(_SCHEMA_VALUE).encode()
        )
        cid = writer.register_channel(
            topic=ch.name,
            message_encoding="json",
            schema_id=schema,
            metadata={"unit": ch.unit} if ch.unit else {},
        )
        ns = np.round(np.asarray(ch.time) * 1e9).astype(np.int64)
        for t, v in zip(ns.tolist(), np.asarray(ch.value, dtype=float).tolist(), strict=True):
            if v == v:  # NaN samples are missing samples
                events.append((t, order, cid, f'{{"value":{_fmt(v, ch.decimals)}}}'.encode()))
        order += 1
    return order


def _group_events(
    writer: Writer, groups: Mapping[str, Mapping[str, str]], by_name: Mapping[str, Channel],
    order: int, events: list[tuple[int, int, int, bytes]],
) -> None:
    """Register one topic per group, its fields the member channels' samples, and append
    its messages to ``events`` as :func:`_channel_events` does, topic order from ``order``."""
    for topic, fields in groups.items():
        members = [by_name[c] for c in fields.values()]
        t0 = np.asarray(members[0].time)
        if any(not np.array_equal(np.asarray(m.time), t0) for m in members):
            raise ConfigError(f"grouped topic '{topic}': its channels must share timestamps")
        units = {m.unit for m in members}
        props = {f: {"type": "number"} for f in fields}
        schema = writer.register_schema(
            name=topic,
            encoding="jsonschema",
            data=json.dumps({"type": "object", "properties": props}).encode(),
        )
        meta = {"unit": units.pop()} if len(units) == 1 and members[0].unit else {}
        cid = writer.register_channel(
            topic=topic, message_encoding="json", schema_id=schema, metadata=meta
        )
        ns = np.round(t0 * 1e9).astype(np.int64).tolist()
        cols = [np.asarray(m.value, dtype=float).tolist() for m in members]
        for i, t in enumerate(ns):
            parts = [
                f'"{f}":{_fmt(col[i], m.decimals)}'
                for f, col, m in zip(fields, cols, members, strict=True)
                if col[i] == col[i]
            ]
            if parts:
                events.append((t, order, cid, ("{" + ",".join(parts) + "}").encode()))
        order += 1


def _union_time(channels: Sequence[Channel]) -> tuple[np.ndarray, list[np.ndarray]]:
    """Sorted union of all timestamps and, per channel, the row of each sample."""
    times = [np.round(np.asarray(c.time, dtype=float), 9) for c in channels]
    grid = np.unique(np.concatenate(times)) if times else np.zeros(0)
    return grid, [np.searchsorted(grid, t) for t in times]


def wide_table(data: SessionData) -> pa.Table:
    """The session as one wide Arrow table: ``time`` plus one nullable float column per
    channel, the unit in each field's metadata and the facts under key ``session``."""
    grid, rows = _union_time(data.channels)
    fields = [pa.field("time", pa.float64(), nullable=False, metadata={"unit": "s"})]
    arrays = [pa.array(grid, type=pa.float64())]
    for ch, idx in zip(data.channels, rows, strict=True):
        col = np.full(grid.size, np.nan)
        col[idx] = np.asarray(ch.value, dtype=float)
        mask = np.isnan(col)
        arrays.append(pa.array(col, type=pa.float64(), mask=mask))
        fields.append(
            pa.field(ch.name, pa.float64(), metadata={"unit": ch.unit} if ch.unit else None)
        )
    schema = pa.schema(fields, metadata={"session": json.dumps(dict(data.facts), sort_keys=True)})
    return pa.Table.from_arrays(arrays, schema=schema)


def csv_bytes(data: SessionData) -> bytes:
    """The session as CSV: ``time`` then ``name [unit]`` columns, empty cells for no sample."""
    grid, rows = _union_time(data.channels)
    header = ["time"] + [f"{c.name} [{c.unit}]" if c.unit else c.name for c in data.channels]
    cells = np.full((grid.size, len(data.channels) + 1), "", dtype=object)
    cells[:, 0] = [f"{t:.6f}".rstrip("0").rstrip(".") for t in grid.tolist()]
    for j, (ch, idx) in enumerate(zip(data.channels, rows, strict=True), start=1):
        vals = np.asarray(ch.value, dtype=float)
        cells[idx, j] = [_fmt(v, ch.decimals) if v == v else "" for v in vals.tolist()]
    lines = [",".join(header)] + [",".join(r) for r in cells.tolist()]
    return ("\n".join(lines) + "\n").encode("utf-8")


TRUTH_SUFFIX = ".truth.parquet"  # simulator truth beside a session: for scoring, never an input


def write_table_parquet(path: str | Path, table: pa.Table, compression: str = "zstd") -> Path:
    """Write any Arrow table atomically as Parquet (used for truth files)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        _write_parquet(table, tmp, compression)
    return path


def _write_parquet(table: pa.Table, path: Path, compression: str) -> None:
    # Byte-stream split makes noisy float columns compress several times better.
    pq.write_table(
        table,
        path,
        compression=None if compression == "none" else compression,
        use_byte_stream_split=[f.name for f in table.schema if pa.types.is_floating(f.type)],
        use_dictionary=False,
    )
