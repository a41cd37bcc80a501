"""Every session file variant of CHANNELS.md, written by the real writers, reads back alike."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from mcap.writer import CompressionType, IndexType, Writer

from brakethermo.io import load_session
from brakethermo.io.session import Session

DURATION_S = 40.0
EPOCH_NS = 1_763_700_000_000_000_000  # an absolute log_time base (2025)
BEACONS = ((5.0, 1), (25.0, 2))
FACTS = {"vehicle": "RC-1", "track": "Mugello", "date": "2026-05-30", "disc": "cc-340-8",
         "ambient_temp_c": "24.5"}

# source name -> (rate Hz, file unit, canonical name). Rates divide 500 Hz so a wide table
# at 500 Hz holds every sample.
CHANNELS: dict[str, tuple[float, str, str]] = {
    "vFront": (100.0, "km/h", "speed"),
    "nWheelF": (100.0, "rpm", "wheel_speed_front"),
    "pBrakeF": (500.0, "bar", "brake_pressure_front"),
    "TDiscFL_1": (50.0, "degC", "disc_temp_spot1"),
    "TDiscFL_2": (50.0, "degC", "disc_temp_spot2"),
    "TDiscFL_3": (50.0, "degC", "disc_temp_spot3"),
    "TDiscFL_4": (50.0, "degC", "disc_temp_spot4"),
    "TAmbient": (1.0, "degF", "ambient_temp"),
    "rideHeight": (20.0, "V", ""),  # extra channel in an unknown unit: must be tolerated
}
GROUP_FIELDS = {"TDiscFL_1": "spot1", "TDiscFL_2": "spot2", "TDiscFL_3": "spot3",
                "TDiscFL_4": "spot4"}


def signal(name: str, t: np.ndarray) -> np.ndarray:
    """Slow, smooth signals: the 10 Hz grid value equals the signal at the grid time."""
    w = 2.0 * np.pi * 0.05
    if name.startswith("TDiscFL_"):
        return 400.0 + 10.0 * int(name[-1]) + 150.0 * np.sin(w * t + 1.0)
    return {
        "vFront": 200.0 + 80.0 * np.sin(w * t),
        "VelocityMain": 55.0 + 20.0 * np.sin(w * t),
        "nWheelF": 1700.0 + 600.0 * np.sin(w * t),
        "pBrakeF": 6.0 + 5.0 * np.cos(w * t),
        "TAmbient": 75.0 + 2.0 * np.sin(0.1 * w * t),
        "rideHeight": 2.5 + 0.1 * t,
    }[name]


def times(rate: float) -> np.ndarray:
    """Sample times on an integer count of 2 ms steps (exact in ns and in float seconds)."""
    step = round(500.0 / rate)
    return np.arange(0, int(DURATION_S * 500) + 1, step) / 500.0


def expected_si(canonical: str, t: np.ndarray) -> np.ndarray:
    src = next(s for s, (_, _, c) in CHANNELS.items() if c == canonical)
    v = signal(src, t)
    return {
        "speed": v / 3.6,
        "wheel_speed_front": v * 2.0 * np.pi / 60.0,
        "brake_pressure_front": v * 1e5,
        "ambient_temp": (v - 32.0) * 5.0 / 9.0,
    }.get(canonical, v)


def write_mcap(
    path: Path, *, grouped: bool = False, epoch: bool = False, shuffle: bool = False,
    compression: CompressionType = CompressionType.ZSTD, chunk_size: int = 16_384,
    use_chunking: bool = True, index: bool = True, slash: bool = False,
    channels: dict[str, tuple[float, str, str]] | None = None,
    payload: str = '{{"value": {v!r}}}', with_session: bool = True,
) -> Path:
    """A session MCAP written with mcap's Writer (JSON messages)."""
    channels = CHANNELS if channels is None else channels
    base = EPOCH_NS if epoch else 0
    records: list[tuple[int, str, bytes]] = []
    group_t = times(50.0)
    for name, (rate, _, _) in channels.items():
        if grouped and name in GROUP_FIELDS:
            continue
        for ti, v in zip(times(rate), signal(name, times(rate)).tolist(), strict=True):
            records.append((base + round(ti * 1e9), name, payload.format(v=v).encode()))
    if grouped:
        spots = {f: signal(n, group_t) for n, f in GROUP_FIELDS.items()}
        for i, ti in enumerate(group_t):
            doc = {f: float(v[i]) for f, v in spots.items()} | {"status": "ok"}
            records.append((base + round(ti * 1e9), "disc_temp", json.dumps(doc).encode()))
    for ti, lap in BEACONS:
        records.append((base + round(ti * 1e9), "lap_beacon", json.dumps({"value": lap}).encode()))
    records.sort(key=lambda r: r[0])  # a logger writes in time order
    order = np.random.default_rng(7).permutation(len(records)) if shuffle else range(len(records))
    with path.open("wb") as fh:
        writer = Writer(fh, chunk_size=chunk_size, compression=compression,
                        use_chunking=use_chunking,
                        index_types=IndexType.ALL if index else IndexType.NONE)
        writer.start()
        schema = writer.register_schema("sample", "jsonschema", b'{"type": "object"}')
        ids: dict[str, int] = {}
        topics = {n: u for n, (_, u, _) in channels.items() if not (grouped and n in GROUP_FIELDS)}
        if grouped:
            topics["disc_temp"] = "degC"
        topics["lap_beacon"] = ""
        for name, unit in topics.items():
            meta = {"unit": unit} if unit else {}
            ids[name] = writer.register_channel(("/" if slash else "") + name, "json", schema, meta)
        for i in order:
            log_time, name, data = records[i]
            writer.add_message(ids[name], log_time, data, log_time)
        if with_session:
            writer.add_metadata("session", FACTS)
        writer.finish()
    return path


def _wide_columns() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    t = times(500.0)
    cols: dict[str, np.ndarray] = {}
    for name, (rate, _, _) in CHANNELS.items():
        col = np.full(t.size, np.nan)
        col[:: round(500.0 / rate)] = signal(name, times(rate))
        cols[name] = col
    beacon = np.full(t.size, np.nan)
    for tb, lap in BEACONS:
        beacon[round(tb * 500)] = lap
    cols["lap_beacon"] = beacon
    return t, cols


def write_parquet(path: Path, *, timestamp: bool = False) -> Path:
    """A wide session table written with pyarrow."""
    t, cols = _wide_columns()
    if timestamp:
        time_arr = pa.array(EPOCH_NS + np.round(t * 1e9).astype(np.int64), pa.timestamp("ns"))
    else:
        time_arr = pa.array(t, pa.float64())
    fields = [pa.field("time", time_arr.type)]
    arrays = [time_arr]
    for name, col in cols.items():
        unit = CHANNELS[name][1] if name in CHANNELS else None
        fields.append(pa.field(name, pa.float64(), metadata={"unit": unit} if unit else None))
        arrays.append(pa.array(col, pa.float64(), mask=np.isnan(col)))
    schema = pa.schema(fields, metadata={"session": json.dumps(FACTS)})
    pq.write_table(pa.Table.from_arrays(arrays, schema=schema), path)
    return path


def write_csv(path: Path) -> Path:
    """A CSV export with ``name [unit]`` headers and empty cells for missing samples."""
    t, cols = _wide_columns()
    header = ["time [s]"] + [
        f"{n} [{CHANNELS[n][1]}]" if n in CHANNELS else n for n in cols
    ]
    with path.open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(header)
        for i in range(t.size):
            row = [repr(float(t[i]))]
            row += ["" if np.isnan(c[i]) else repr(float(c[i])) for c in cols.values()]
            out.writerow(row)
    return path


def lap_rows(session: Session) -> np.ndarray:
    return np.array([(lap.lap, lap.start_s, lap.duration_s) for lap in session.laps])


def check_session(session: Session) -> None:
    """Independent check of a loaded session against the analytic signals in SI."""
    frame = session.frame
    grid_t = np.arange(int(DURATION_S * 10) + 1) * 0.1
    np.testing.assert_allclose(frame["time"].to_numpy(), grid_t, atol=1e-9)
    for canonical in ("speed", "wheel_speed_front", "brake_pressure_front", "disc_temp_spot1",
                      "disc_temp_spot4", "ambient_temp"):
        want = expected_si(canonical, grid_t)
        got = frame[canonical].to_numpy()
        scale = np.ptp(want) + np.abs(want).max() * 1e-6
        np.testing.assert_allclose(got, want, atol=2e-3 * scale, err_msg=canonical)
    assert "rideHeight" in session.available
    assert "rideHeight" not in frame.columns
    assert session.channels["brake_pressure_front"].samples == int(DURATION_S * 500) + 1
    assert session.channels["brake_pressure_front"].rate_hz == pytest.approx(500.0)
    assert session.channels["speed"].unit == "km/h"
    assert session.channels["speed"].si_unit == "m/s"
    np.testing.assert_allclose(lap_rows(session), [(0, 0, 5), (1, 5, 20), (2, 25, 15)],
                               atol=1e-9)
    lap = frame["lap"].to_numpy()
    assert lap[0] == 0 and lap[49] == 0 and lap[50] == 1 and lap[250] == 2 and lap[-1] == 2
    assert all(not c.gaps for c in session.channels.values())


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Session:
    path = write_mcap(tmp_path_factory.mktemp("ref") / "ref.mcap")
    session = load_session(path)
    check_session(session)
    assert session.metadata == FACTS
    assert session.start_epoch_s is None
    return session


def assert_same(session: Session, reference: Session) -> None:
    assert list(session.frame.columns) == list(reference.frame.columns)
    np.testing.assert_allclose(
        session.frame.to_numpy(dtype=float), reference.frame.to_numpy(dtype=float),
        rtol=1e-9, atol=1e-9,
    )
    np.testing.assert_allclose(lap_rows(session), lap_rows(reference), atol=1e-9)


MCAP_VARIANTS = {
    "grouped": {"grouped": True},
    "epoch": {"epoch": True},
    "shuffled": {"shuffle": True},
    "lz4": {"compression": CompressionType.LZ4},
    "none": {"compression": CompressionType.NONE},
    "shuffled-epoch-lz4-grouped": {"shuffle": True, "epoch": True, "grouped": True,
                                   "compression": CompressionType.LZ4},
    "leading-slash": {"slash": True},
    "unchunked": {"use_chunking": False},
    "no-message-index": {"index": False, "shuffle": True},
    "compact-json": {"payload": '{{"value":{v!r}}}'},
    "extra-fields": {"payload": '{{"value": {v!r}, "status": "ok", "valid": true}}'},
}


@pytest.mark.parametrize("variant", list(MCAP_VARIANTS))
def test_mcap_variants_round_trip(variant: str, tmp_path: Path, reference: Session) -> None:
    session = load_session(write_mcap(tmp_path / f"{variant}.mcap", **MCAP_VARIANTS[variant]))
    check_session(session)
    assert_same(session, reference)
    assert session.metadata == FACTS
    if MCAP_VARIANTS[variant].get("epoch"):
        assert session.start_epoch_s == pytest.approx(EPOCH_NS * 1e-9)
    if MCAP_VARIANTS[variant].get("grouped"):
        assert session.channels["disc_temp_spot3"].source == "disc_temp.spot3"
        assert "disc_temp.status" not in session.available


@pytest.mark.parametrize("timestamp", [False, True], ids=["float-s", "timestamp-ns"])
def test_parquet_round_trip(timestamp: bool, tmp_path: Path, reference: Session) -> None:
    session = load_session(write_parquet(tmp_path / "s.parquet", timestamp=timestamp))
    check_session(session)
    assert_same(session, reference)
    assert session.metadata == FACTS
    assert (session.start_epoch_s is not None) == timestamp


def test_csv_round_trip(tmp_path: Path, reference: Session) -> None:
    session = load_session(write_csv(tmp_path / "S.CSV"))
    check_session(session)
    assert_same(session, reference)


def test_truncated_mcap_recovers_intact_part(tmp_path: Path) -> None:
    full = write_mcap(tmp_path / "full.mcap", chunk_size=8_192)
    data = full.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    session = load_session(cut)
    assert len(session.warnings) >= 1
    warning = session.warnings[0]
    assert "truncated" in warning and "bytes" in warning and "%" in warning and "t = " in warning
    reference = load_session(full)
    n = len(session.frame)
    assert 0.3 * len(reference.frame) < n < len(reference.frame)
    # The intact part matches the full file away from the cut (its last second may differ).
    head = n - 15
    np.testing.assert_allclose(
        session.frame["speed"].to_numpy()[:head], reference.frame["speed"].to_numpy()[:head],
        rtol=1e-9,
    )


def test_huge_sparse_tail_is_read_in_moments_not_walked(tmp_path: Path) -> None:
    """A log cut after 60 % and then padded with 1 GiB of zeros (a sparse file: the
    recorder preallocated it) is memory-mapped, not read, and the walk stops at the first
    zeroed record instead of stepping through a billion bytes."""
    full = write_mcap(tmp_path / "full.mcap", chunk_size=8_192)
    data = full.read_bytes()
    padded = tmp_path / "padded.mcap"
    cut = int(len(data) * 0.6)
    padded.write_bytes(data[:cut])
    with padded.open("r+b") as f:
        f.truncate(1 << 30)
    session = load_session(padded)
    warning = next(w for w in session.warnings if "truncated or damaged" in w)
    at = int(warning.split("at byte ")[1].split()[0])
    assert at < 2 * cut and f"of {1 << 30}" in warning  # stopped where the zeros begin
    assert 0.3 * len(load_session(full).frame) < len(session.frame)


def test_aliases_override_file(tmp_path: Path) -> None:
    channels = {"VelocityMain": (100.0, "m/s", "speed"), "vFront": (100.0, "km/h", "speed")}
    path = write_mcap(tmp_path / "a.mcap", channels=channels)
    assert load_session(path).channels["speed"].source == "vFront"
    table = tmp_path / "team.toml"
    table.write_text('[aliases]\nspeed = ["VelocityMain"]\n')
    session = load_session(path, aliases=table)
    assert session.channels["speed"].source == "VelocityMain"
    assert session.aliases["speed"][0] == "VelocityMain"
    assert "vFront" in session.aliases["speed"]  # the shipped names are still tried after


@pytest.mark.parametrize("use_chunking", [True, False])
def test_the_compiled_walk_reads_the_same_in_any_batch(tmp_path: Path, use_chunking: bool,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """The record walk of files without message indexes (``io/_mcap_walk.py``) gives the
    same session whether it walks a million records per call or three, chunked or not,
    whole or cut."""
    from brakethermo.io import _mcap_walk

    full = write_mcap(tmp_path / "full.mcap", index=False, chunk_size=8_192,
                      use_chunking=use_chunking)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full.read_bytes()[: int(full.stat().st_size * 0.7)])
    whole = {p: load_session(p) for p in (full, cut)}
    monkeypatch.setattr(_mcap_walk, "BATCH", 3)
    for path, reference in whole.items():
        small = load_session(path)
        assert small.frame.equals(reference.frame)
        assert small.warnings == reference.warnings
    assert any("truncated" in w for w in whole[cut].warnings)


def test_the_walk_stops_at_a_record_longer_than_any_file() -> None:
    """A length with its top bit set (garbage) is a cut, not a jump backwards."""
    from brakethermo.io._mcap_walk import OPCODE_MESSAGE, walk

    good = bytes([OPCODE_MESSAGE]) + (3).to_bytes(8, "little") + b"abc"
    bad = bytes([OPCODE_MESSAGE]) + (1 << 63).to_bytes(8, "little")
    buf = np.frombuffer(good + bad + good, dtype=np.uint8)
    messages, others, stop, complete = walk(buf, 0, buf.size)
    assert messages.tolist() == [0] and others.size == 0
    assert stop == len(good) and not complete
