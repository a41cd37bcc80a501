"""MCAP session reader (CHANNELS.md §1): JSON messages, per-channel or grouped topics.

Two ways through a file, both decoding message payloads in bulk with numpy:

* **indexed** (a complete file with a summary): the library's summary gives the chunk
  indexes, the message index after each chunk gives every message's offset in the
  decompressed chunk;
* **sequential** (no summary or message index, or a truncated file): the records are
  walked one by one (chunk by chunk, the library parsing each Chunk, Channel and
  Metadata record); a truncated file keeps every intact record and says how much
  was lost.

Every chunk's CRC (when the writer stored one) is checked after decompression: a
corrupt chunk — bad CRC, or data that will not decompress — is skipped with a warning
naming the time range it held, and every intact chunk is still read.

Payloads of the exact form ``{"value": <number>}`` are parsed as fixed-width numbers;
any other JSON object is decoded with :class:`JsonDecoderFactory`, one parser call per
channel and chunk.
"""

from __future__ import annotations

import json
import mmap
import struct
import zlib
from collections import defaultdict
from collections.abc import Callable, Iterator, Sequence
from io import BytesIO
from pathlib import Path
from typing import Any

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.decoder import DecoderFactory
from mcap.exceptions import InvalidMagic, McapError
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Metadata, Schema
from mcap.summary import Summary

from brakethermo.errors import DataError
from brakethermo.io.raw import Format, RawChannel, RawSession, rebase_ns

_MAGIC_SIZE = 8
_OPCODE_CHANNEL = 0x04
_OPCODE_MESSAGE = 0x05
_OPCODE_CHUNK = 0x06
_OPCODE_MESSAGE_INDEX = 0x07
_OPCODE_METADATA = 0x0C
_RECORD_HEAD = struct.Struct("<BQ")  # every record: opcode u8, body length u64
# Message record: opcode u8, length u64, channel_id u16, sequence u32, log_time u64,
# publish_time u64, then the payload.
_MESSAGE_HEADER = 1 + 8 + 2 + 4 + 8 + 8
_VALUE_PREFIX = np.frombuffer(b'{"value":', dtype=np.uint8)
_MAX_NUMBER_CHARS = 40
# What the library raises when a record is cut short or its chunk will not decompress.
_TRUNCATION_ERRORS = (
    McapError, struct.error, ValueError, EOFError, OSError, RuntimeError, zstandard.ZstdError
)


def _decode_json(data: bytes) -> Any:
    try:
        return json.loads(data)
    except RecursionError:
        raise ValueError("JSON nested too deeply") from None


class JsonDecoderFactory(DecoderFactory):
    """Decoder factory for ``message_encoding = "json"`` (the core ``mcap`` has none)."""

    def decoder_for(
        self, message_encoding: str, schema: Schema | None
    ) -> Callable[[bytes], Any] | None:
        """Return a JSON decoder for JSON channels, ``None`` for any other encoding."""
        if message_encoding == "json":
            return _decode_json
        return None


class _Corrupt(Exception):
    """The file's indexes or records cannot be trusted."""


class _BadChunk(Exception):
    """One chunk fails its CRC or will not decompress: skip it, keep the others."""


# What a damaged chunk raises on the way to its records.
_CHUNK_ERRORS = (_BadChunk, *_TRUNCATION_ERRORS)


def _topic(channel: Channel) -> str:
    return channel.topic.lstrip("/")


def _unit(channel: Channel, key: str) -> str | None:
    """Unit of a field: ``unit.<field>`` metadata first, then the channel's ``unit``."""
    return channel.metadata.get(f"unit.{key}", channel.metadata.get("unit"))


class _Collector:
    """Native samples per source channel, as lists of array pieces."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.times: dict[str, list[np.ndarray]] = defaultdict(list)
        self.values: dict[str, list[np.ndarray]] = defaultdict(list)
        self.units: dict[str, str | None] = {}
        self.order: list[str] = []
        # (byte offset, first and last log_time in ns or None, reason) per skipped chunk
        self.lost: list[tuple[int, int | None, int | None, str]] = []
        self.known: dict[int, Channel] = {}  # every Channel record seen

    def add_silent(self) -> None:
        """Channels registered in the file but without a single message, as empty channels
        (so that a required one is reported as empty, not as absent)."""
        for channel in self.known.values():
            topic = _topic(channel)
            if topic not in self.units and not any(n.startswith(topic + ".") for n in self.order):
                self.add(topic, _unit(channel, "value"), np.empty(0, np.int64), np.empty(0))

    def add(self, name: str, unit: str | None, t_ns: np.ndarray, v: np.ndarray) -> None:
        if name not in self.units:
            self.units[name] = unit
            self.order.append(name)
        elif (unit or "").strip() != (self.units[name] or "").strip():
            raise DataError(
                f"registered twice with different units ('{self.units[name] or 'none'}' and "
                f"'{unit or 'none'}'): the samples cannot be merged into one channel; log "
                "one unit per topic", path=self.path, channel=name)
        self.times[name].append(t_ns)
        self.values[name].append(v)

    def add_docs(self, channel: Channel, t_ns: np.ndarray, docs: Sequence[Any]) -> None:
        """Split decoded JSON objects into channels: ``value`` -> topic, others -> topic.field."""
        topic = _topic(channel)
        keys: dict[str, None] = {}
        for doc in docs:
            if not isinstance(doc, dict):
                raise DataError(
                    f"message is not a JSON object ({type(doc).__name__}); expected"
                    ' {"value": number} or an object of numeric fields',
                    path=self.path,
                    channel=topic,
                )
            keys.update(dict.fromkeys(doc))
        for key in keys:
            name = topic if key == "value" else f"{topic}.{key}"
            raw = [doc.get(key) for doc in docs]
            numeric = np.array(
                [isinstance(x, int | float) and not isinstance(x, bool) for x in raw]
            )
            present = np.array([x is not None for x in raw])
            if not numeric.any() and key != "value":
                continue  # a text/flag/object field is not a channel
            bad = present & ~numeric
            if bad.any():
                first = int(np.argmax(bad))
                raise DataError(
                    f"non-numeric value {raw[first]!r} in field '{key}' at log_time"
                    f" {int(t_ns[first])} ns; every sample must be a number",
                    path=self.path,
                    channel=name,
                )
            v = np.array([x if x is not None else np.nan for x in raw], dtype=np.float64)
            self.add(name, _unit(channel, key), t_ns[present], v[present])

    def span_s(self) -> float:
        """Time from the earliest to the latest sample collected so far, s."""
        pieces = [t for ts in self.times.values() for t in ts if t.size]
        return (max(int(t.max()) for t in pieces) - min(int(t.min()) for t in pieces)) * 1e-9

    def lost_warnings(self) -> list[str]:
        """One warning per skipped corrupt chunk, with its time range from the session start."""
        pieces = [t for ts in self.times.values() for t in ts if t.size]
        t0 = min((int(t.min()) for t in pieces), default=0)
        out = []
        for offset, start, end, reason in self.lost:
            span = (
                f"messages from t = {(start - t0) * 1e-9:.2f} s to {(end - t0) * 1e-9:.2f} s"
                " are lost"
                if start is not None and end is not None
                else "its messages are lost (time range unreadable)"
            )
            out.append(f"corrupt chunk at byte {offset} ({reason}): skipped; {span}")
        return out

    def build(self, metadata: dict[str, str], warnings: list[str]) -> RawSession:
        warnings = [*warnings, *self.lost_warnings()]
        times = [np.concatenate(self.times[n]) for n in self.order]
        values = [np.concatenate(self.values[n]) for n in self.order]
        times_s, epoch = rebase_ns(times)
        channels = tuple(
            RawChannel(n, t, v, self.units[n])
            for n, t, v in zip(self.order, times_s, values, strict=True)
        )
        return RawSession(self.path, channels, metadata, epoch, tuple(warnings))


def _check_encodings(path: Path, channels: Sequence[Channel]) -> None:
    factory = JsonDecoderFactory()
    for channel in channels:
        if factory.decoder_for(channel.message_encoding, None) is None:
            raise DataError(
                f"message encoding '{channel.message_encoding}' is not supported; only JSON"
                ' messages (message_encoding "json") can be read. Re-export the log with'
                " JSON messages",
                path=path,
                channel=_topic(channel),
            )


def _decompress(chunk: Chunk) -> bytes:
    """The chunk's records, CRC-checked (raises :class:`_BadChunk` when damaged)."""
    try:
        if chunk.compression == "zstd":
            data = zstandard.ZstdDecompressor().decompress(
                chunk.data, max_output_size=chunk.uncompressed_size
            )
        elif chunk.compression == "lz4":
            data = lz4.frame.decompress(chunk.data)
        elif chunk.compression == "":
            data = chunk.data
        else:
            raise _Corrupt(f"unknown chunk compression '{chunk.compression}'")
    except _TRUNCATION_ERRORS:
        raise _BadChunk(f"{chunk.compression} data will not decompress") from None
    if len(data) != chunk.uncompressed_size:
        raise _BadChunk("wrong decompressed size")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise _BadChunk("CRC mismatch")
    return data


def _gather(buf: np.ndarray, start: np.ndarray, width: int) -> np.ndarray:
    """Rows ``buf[start_i : start_i + width]`` as an (n, width) uint8 array (clipped at the end)."""
    idx = start[:, None] + np.arange(width)[None, :]
    np.minimum(idx, buf.size - 1, out=idx)
    return buf[idx]


def _fast_values(buf: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray | None:
    """Parse payloads of the exact form ``{"value": <number>}`` in bulk; ``None`` otherwise."""
    if (end - start < _VALUE_PREFIX.size + 2).any():
        return None
    if not (_gather(buf, start, _VALUE_PREFIX.size) == _VALUE_PREFIX).all():
        return None
    if not (buf[end - 1] == ord("}")).all():
        return None
    num_start = start + _VALUE_PREFIX.size
    num_start += buf[num_start] == ord(" ")
    num_end = end - 1
    num_end -= buf[num_end - 1] == ord(" ")
    length = num_end - num_start
    if length.size == 0:
        return np.empty(0)
    width = int(length.max())
    if length.min() <= 0 or width > _MAX_NUMBER_CHARS:
        return None
    chars = _gather(buf, num_start, width)
    chars[np.arange(width)[None, :] >= length[:, None]] = 0  # NUL-padded fixed-width bytes
    try:
        return np.ascontiguousarray(chars).view(f"S{width}").ravel().astype(np.float64)
    except ValueError:
        return None


def _json_docs(data: bytes, start: np.ndarray, end: np.ndarray) -> list[Any]:
    """Decode many JSON payloads with one parser call (a JSON array of them)."""
    pieces = [data[a:b] for a, b in zip(start.tolist(), end.tolist(), strict=True)]
    try:
        return json.loads(b"[" + b",".join(pieces) + b"]")
    except (ValueError, RecursionError):
        decode = JsonDecoderFactory().decoder_for("json", None)
        assert decode is not None
        return [decode(p) for p in pieces]  # raises at the first bad payload


def _add_block(
    out: _Collector, channel: Channel, data: bytes, buf: np.ndarray, t_ns: np.ndarray,
    offset: np.ndarray,
) -> None:
    """Decode the message records of one channel at ``offset`` of a record buffer."""
    if (offset + _MESSAGE_HEADER > buf.size).any() or (buf[offset] != _OPCODE_MESSAGE).any():
        raise _Corrupt("an offset does not point at a message record")
    length = np.ascontiguousarray(_gather(buf, offset + 1, 8)).view("<u8").ravel()
    start = offset + _MESSAGE_HEADER
    end = offset + 9 + length.astype(np.int64)
    if (end > buf.size).any() or (end < start).any():
        raise _Corrupt("a message record runs past its buffer")
    values = _fast_values(buf, start, end)
    if values is not None:
        out.add(_topic(channel), _unit(channel, "value"), t_ns, values)
        return
    try:
        docs = _json_docs(data, start, end)
    except ValueError:
        raise DataError(
            "a message is not valid JSON (or nested too deeply); every message must be a flat"
            " JSON object",
            path=out.path,
            channel=_topic(channel),
        ) from None
    out.add_docs(channel, t_ns, docs)


def _message_indexes(block: bytes) -> Iterator[tuple[int, np.ndarray]]:
    """(channel_id, entries[n, 2] of (log_time, offset)) for each MessageIndex record."""
    pos = 0
    while pos + 9 <= len(block):
        opcode, length = _RECORD_HEAD.unpack_from(block, pos)
        body = pos + 9
        if opcode == _OPCODE_MESSAGE_INDEX:
            channel_id, n_bytes = struct.unpack_from("<HI", block, body)
            entries = np.frombuffer(block, dtype="<u8", count=n_bytes // 8, offset=body + 6)
            yield channel_id, entries.reshape(-1, 2)
        pos = body + length


def _indexed_usable(summary: Summary | None) -> bool:
    return (
        summary is not None
        and len(summary.chunk_indexes) > 0
        and all(ci.message_index_length > 0 for ci in summary.chunk_indexes)
    )


def _read_indexed(f: Any, summary: Summary, out: _Collector) -> None:
    """Bulk path over chunk and message indexes; raises :class:`_Corrupt` if they disagree."""
    for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        f.seek(ci.chunk_start_offset + 9)
        try:
            data = _decompress(Chunk.read(ReadDataStream(f)))
        except _CHUNK_ERRORS as exc:
            reason = str(exc) if isinstance(exc, _BadChunk) else "unreadable chunk record"
            out.lost.append((ci.chunk_start_offset, ci.message_start_time,
                             ci.message_end_time, reason))
            continue
        buf = np.frombuffer(data, dtype=np.uint8)
        f.seek(ci.chunk_start_offset + ci.chunk_length)
        for channel_id, entries in _message_indexes(f.read(ci.message_index_length)):
            if entries.size == 0:
                continue
            if channel_id not in summary.channels:
                raise _Corrupt(f"message index for unknown channel {channel_id}")
            _add_block(out, summary.channels[channel_id], data, buf, entries[:, 0],
                       entries[:, 1].astype(np.int64))


def _add_records(
    out: _Collector, channels: dict[int, Channel], data: bytes, offsets: np.ndarray
) -> None:
    """Decode message records at ``offsets`` of ``data``, grouped by channel."""
    if len(offsets) == 0:
        return
    buf = np.frombuffer(data, dtype=np.uint8)
    offset = np.asarray(offsets, dtype=np.int64)
    channel_id = np.ascontiguousarray(_gather(buf, offset + 9, 2)).view("<u2").ravel()
    log_time = np.ascontiguousarray(_gather(buf, offset + 15, 8)).view("<u8").ravel()
    for cid in np.unique(channel_id).tolist():
        if cid not in channels:
            raise _Corrupt(f"a message of channel {cid} comes before its Channel record")
        mine = channel_id == cid
        _add_block(out, channels[cid], data, buf, log_time[mine], offset[mine])


def _walk(
    data: Any, pos: int, end: int, channels: dict[int, Channel], metadata: dict[str, str]
) -> tuple[np.ndarray, list[int], int, bool]:
    """Walk the records of ``data[pos:end]``.

    Returns the offsets of Message records and of Chunk records, the offset just after
    the last complete record, and whether the walk reached the DataEnd record. Channel
    and ``session`` Metadata records are parsed on the way (by the library).
    """
    from brakethermo.io._mcap_walk import walk

    messages, others, stop, complete = walk(np.frombuffer(data, dtype=np.uint8), pos, end)
    chunks: list[int] = []
    for at in others.tolist():
        opcode, length = _RECORD_HEAD.unpack_from(data, at)
        body = data[at + 9: at + 9 + length]
        if opcode == _OPCODE_CHUNK:
            chunks.append(at)
        elif opcode == _OPCODE_CHANNEL:
            record = Channel.read(ReadDataStream(BytesIO(body)))
            channels[record.id] = record
        elif opcode == _OPCODE_METADATA:
            meta = Metadata.read(ReadDataStream(BytesIO(body)))
            if meta.name == "session":
                metadata.update(meta.metadata)
    return messages, chunks, stop, complete


def _read_sequential(path: Path, out: _Collector) -> tuple[dict[str, str], list[str]]:
    """Record-by-record path; recovers the intact part of a truncated file.

    The file is memory-mapped, not read: a huge, mostly empty file costs only the pages
    the walk touches.
    """
    with path.open("rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
        return _read_mapped(path, data, out)


def _read_mapped(path: Path, data: Any, out: _Collector) -> tuple[dict[str, str], list[str]]:
    size = len(data)
    channels = out.known
    metadata: dict[str, str] = {}
    messages, chunks, last_good, complete = _walk(data, _MAGIC_SIZE, size, channels, metadata)
    _check_encodings(path, list(channels.values()))
    _add_records(out, channels, data, messages)
    for pos in chunks:
        # Every listed chunk record is complete (the walk stops at a cut one): a chunk
        # that fails here is damaged, not truncated; skip it and read the next.
        chunk = None
        try:
            _, length = _RECORD_HEAD.unpack_from(data, pos)
            chunk = Chunk.read(ReadDataStream(BytesIO(data[pos + 9 : pos + 9 + length])))
            inner = _decompress(chunk)
        except _CHUNK_ERRORS as exc:
            reason = str(exc) if isinstance(exc, _BadChunk) else "unreadable chunk record"
            span = (chunk.message_start_time, chunk.message_end_time) if chunk else (None, None)
            out.lost.append((pos, *span, reason))
            continue
        known = len(channels)
        messages, _, _, _ = _walk(inner, 0, len(inner), channels, metadata)
        if len(channels) > known:
            _check_encodings(path, list(channels.values()))
        _add_records(out, channels, inner, messages)
    warnings: list[str] = []
    if not complete:
        if not out.order:
            raise DataError(
                "not a readable MCAP file: it is damaged or truncated before any message",
                path=path,
            )
        lost = size - last_good
        warnings.append(
            f"file is truncated or damaged at byte {last_good} of {size}: the last {lost} bytes"
            f" ({100.0 * lost / size:.1f} % of the file) could not be read and their messages"
            f" are lost; data end at t = {out.span_s():.2f} s"
        )
    return metadata, warnings


def read_mcap(path: Path) -> RawSession:
    """Read an MCAP session file into native-rate channels.

    Parameters
    ----------
    path : Path
        The ``.mcap`` file.

    Returns
    -------
    RawSession
        Channels named by topic (leading ``/`` removed) or ``topic.field``, times in s
        from the earliest message, units from the channel metadata key ``unit``, the
        ``session`` metadata record, and a warning if a truncated file was recovered.

    Raises
    ------
    DataError
        Not an MCAP file, no channels or messages, a non-JSON message encoding, a
        non-numeric sample, or a file damaged before any message.
    """
    out = _Collector(path)
    metadata: dict[str, str] = {}
    warnings: list[str] = []
    done = False
    with path.open("rb") as f:
        try:
            reader = make_reader(f, decoder_factories=[JsonDecoderFactory()])
        except (InvalidMagic, *_TRUNCATION_ERRORS):
            raise DataError(
                "not a valid MCAP file (bad magic bytes at the start); check that it is an"
                " .mcap log and not damaged",
                path=path,
            ) from None
        try:
            summary = reader.get_summary()
        except _TRUNCATION_ERRORS:
            summary = None
        if _indexed_usable(summary):
            assert summary is not None
            _check_encodings(path, list(summary.channels.values()))
            out.known.update(summary.channels)
            try:
                _read_indexed(f, summary, out)
                for record in reader.iter_metadata():
                    if record.name == "session":
                        metadata.update(record.metadata)
                done = True
            except (_Corrupt, *_TRUNCATION_ERRORS):
                out = _Collector(path)
    if not done:
        try:
            metadata, warnings = _read_sequential(path, out)
        except _Corrupt as exc:
            raise DataError(f"not a readable MCAP file: {exc}", path=path) from None
    if not out.order:
        if out.lost:
            raise DataError(
                f"not a readable MCAP file: all {len(out.lost)} chunk(s) are corrupt"
                f" ({out.lost[0][3]}); nothing could be recovered",
                path=path,
            )
        raise DataError(
            "the MCAP file holds no channels with messages; nothing to read", path=path
        )
    out.add_silent()
    return out.build(metadata, warnings)


FORMAT = Format("MCAP", (".mcap",), read_mcap, time_ordered=False)
