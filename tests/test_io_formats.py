"""MDF (asammdf) and AiM XRK (libxrk) readers, the reader registry, and the bad-input
behaviour of CHANNELS.md for every format: one clear line, exit 1, no traceback.

MDF files are written by asammdf itself. XRK: libxrk has no writer and ships no sample
file, so the XRK tests hand the reader a ``libxrk.LogFile`` (the library's own result
type) built here, in place of a parsed file; the real parser runs only on damaged bytes.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from asammdf import MDF, Signal
from asammdf.blocks.source_utils import Source
from test_io_roundtrip import (  # noqa: F401  (reference is a fixture)
    BEACONS,
    CHANNELS,
    FACTS,
    assert_same,
    check_session,
    reference,
    signal,
    times,
)
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.errors import DataError
from brakethermo.io import load_session
from brakethermo.io.formats import BY_SUFFIX, FORMATS
from brakethermo.io.session import Session
from brakethermo.io.writers import Channel, SessionData, csv_bytes, mcap_bytes, wide_table

try:
    import libxrk
except ImportError:  # an optional dependency: wheels for some platforms only
    libxrk = None
needs_libxrk = pytest.mark.skipif(libxrk is None, reason="libxrk is not installed")

START = dt.datetime(2026, 5, 30, 12, 0, 0, tzinfo=dt.UTC)
GROUP_RATES = (500.0, 100.0, 50.0, 20.0, 1.0)


def write_mdf(path: Path, *, version: str = "4.10") -> Path:
    """The CHANNELS session as MDF: one channel group per rate, a value-to-text channel."""
    mdf = MDF(version=version)
    mdf.header.start_time = START
    if version >= "4":
        props = "".join(f'<e name="{k}">{v}</e>' for k, v in FACTS.items())
        mdf.header.comment = (f"<HDcomment><TX>test session</TX><common_properties>{props}"
                              "</common_properties></HDcomment>")
    for rate in GROUP_RATES:
        t = times(rate)
        sigs = [Signal(signal(n, t), t, name=n, unit=u)
                for n, (r, u, _) in CHANNELS.items() if r == rate]
        if rate == 1.0:
            conv = {"val_0": 0, "text_0": "OK", "val_1": 1, "text_1": "FAULT", "default": b"?"}
            sigs.append(Signal((t.astype(int) % 2).astype(np.uint8), t, name="sensor_state",
                               conversion=conv))
        mdf.append(sigs, comment=f"{rate:g} Hz")
    tb = np.array([b for b, _ in BEACONS])
    mdf.append([Signal(np.array([lap for _, lap in BEACONS], dtype=np.uint16), tb,
                       name="lap_beacon")], comment="beacons")
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


def _xrk_table(name: str, t_s: np.ndarray, v: np.ndarray, unit: str) -> pa.Table:
    field = pa.field(name, pa.float64(), metadata={b"units": unit.encode()})
    tc = pa.array(np.round(t_s * 1e3).astype(np.int64))
    return pa.Table.from_arrays([tc, pa.array(v, pa.float64())],
                                schema=pa.schema([pa.field("timecodes", pa.int64()), field]))


def fake_xrk(monkeypatch: pytest.MonkeyPatch, channels: dict[str, tuple[np.ndarray, np.ndarray,
             str]], laps: list[tuple[int, float, float]] | None = None) -> None:
    """Make libxrk 'parse' any file into a LogFile holding ``channels``."""
    lap_rows = laps or []
    lap_table = pa.table({
        "num": [n for n, _, _ in lap_rows],
        "start_time": [round(a * 1e3) for _, a, _ in lap_rows],
        "end_time": [round(b * 1e3) for _, _, b in lap_rows],
        "lap_type": ["out" if n == 0 else "full" for n, _, _ in lap_rows],
    }) if laps is not None else None  # fmt: skip
    log = libxrk.LogFile(
        channels={n: _xrk_table(n, t, v, u) for n, (t, v, u) in channels.items()},
        laps=lap_table,
        metadata={"Vehicle": "RC-1", "Venue": "Mugello", "Log Date": "30/05/2026",
                  "Log Time": "12:00:00", "Driver": "A. Driver"},
        file_name="s.xrk",
    )
    monkeypatch.setattr(libxrk, "aim_xrk", lambda *_a, **_k: log)


def xrk_channels() -> dict[str, tuple[np.ndarray, np.ndarray, str]]:
    return {n: (times(r), signal(n, times(r)), u) for n, (r, u, _) in CHANNELS.items()}


# -- round trips: the same 10 Hz channels as the reference MCAP, to 1e-9 -----------------


@pytest.mark.parametrize("version", ["4.10", "3.30"])
def test_mdf_round_trip(version: str, tmp_path: Path, reference: Session) -> None:  # noqa: F811
    suffix = ".mf4" if version >= "4" else ".mdf"
    session = load_session(write_mdf(tmp_path / f"s{suffix}", version=version))
    check_session(session)
    assert_same(session, reference)
    assert session.format == f"MDF {version}"
    assert session.start_epoch_s == pytest.approx(START.timestamp())
    assert session.metadata["date"] == ("2026-05-30")
    if version >= "4":
        assert {k: session.metadata[k] for k in FACTS} == FACTS
        assert session.metadata["comment"] == "test session"
    # each group's own time base survives until resampling
    assert session.channels["brake_pressure_front"].rate_hz == pytest.approx(500.0)
    assert session.channels["ambient_temp"].rate_hz == pytest.approx(1.0)
    assert any("sensor_state" in w and "value-to-text" in w for w in session.warnings)


def test_mdf_bus_log_without_signals(tmp_path: Path) -> None:
    mdf = MDF(version="4.10")
    t = np.arange(50) * 0.01
    frames = np.zeros(t.size, dtype=[("CAN_DataFrame.ID", "<u4"),
                                     ("CAN_DataFrame.DataBytes", "u1", (8,))])
    mdf.append([Signal(frames, t, name="CAN_DataFrame")],
               acq_source=Source("CAN1", "CAN1", "", Source.SOURCE_BUS, Source.BUS_TYPE_CAN))
    path = tmp_path / "bus.mf4"
    mdf.save(path, overwrite=True)
    with pytest.raises(DataError, match=r"no numeric channel.*raw bus log.*DBC"):
        load_session(path)


@needs_libxrk
def test_xrk_round_trip(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                        reference: Session) -> None:  # noqa: F811
    fake_xrk(monkeypatch, xrk_channels(), laps=[(0, 0.0, 5.0), (1, 5.0, 25.0), (2, 25.0, 40.0)])
    path = tmp_path / "s.xrk"
    path.write_bytes(b"placeholder")
    session = load_session(path)
    check_session(session)
    assert_same(session, reference)
    assert session.format == "AiM XRK"
    assert session.metadata["vehicle"] == "RC-1" and session.metadata["track"] == "Mugello"
    assert session.start_epoch_s == pytest.approx(START.timestamp())


def test_xrk_without_libxrk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(__import__("sys").modules, "libxrk", None)  # import fails
    path = tmp_path / "s.xrk"
    path.write_bytes(b"placeholder")
    with pytest.raises(DataError, match=r"needs the optional package libxrk.*brakethermo\[xrk\]"):
        load_session(path)
    # the other formats do not need it
    csv = tmp_path / "s.csv"
    csv.write_text("time,vFront [km/h]\n0,1\n0.1,2\n")
    assert load_session(csv).has("speed")


@needs_libxrk
def test_xrk_damaged_bytes_real_parser(tmp_path: Path) -> None:
    path = tmp_path / "junk.xrk"
    path.write_bytes(np.random.default_rng(3).bytes(3000))
    with pytest.raises(DataError, match=r"no channel.*damaged or not an AiM"):
        load_session(path)


def test_registry_is_one_line_per_format() -> None:
    names = [f.name for f in FORMATS]
    assert names == ["MCAP", "Parquet", "CSV", "MDF", "AiM XRK"]
    assert set(BY_SUFFIX) == {".mcap", ".parquet", ".csv", ".mf4", ".mdf", ".mf3", ".xrk", ".xrz"}


# -- the same bad inputs in every format ---------------------------------------------------

Spec = dict[str, tuple[np.ndarray, np.ndarray, str]]


def _t(n: int = 200, rate: float = 50.0) -> np.ndarray:
    return np.arange(n) / rate


def write_any(fmt: str, path_stem: Path, chans: Spec, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Write ``chans`` ({name: (t s, values, unit)}) with the format's real writer."""
    path = path_stem.with_suffix({"mcap": ".mcap", "parquet": ".parquet", "csv": ".csv",
                                  "mdf": ".mf4", "xrk": ".xrk"}[fmt])
    data = SessionData(tuple(Channel(n, u, t, v, decimals=6) for n, (t, v, u) in chans.items()))
    if fmt == "mcap":
        path.write_bytes(mcap_bytes(data))
    elif fmt == "parquet":
        import pyarrow.parquet as pq

        pq.write_table(wide_table(data), path)
    elif fmt == "csv":
        path.write_bytes(csv_bytes(data))
    elif fmt == "mdf":
        mdf = MDF(version="4.10")
        for n, (t, v, u) in chans.items():
            mdf.append([Signal(np.asarray(v, dtype=float), t, name=n, unit=u)])
        mdf.save(path, overwrite=True)
        mdf.close()
    else:
        fake_xrk(monkeypatch, chans)
        path.write_bytes(b"placeholder")
    return path


def cli_error(args: list[str], *phrases: str) -> str:
    result = CliRunner().invoke(app, ["inspect", *args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert result.exit_code == 1, result.output
    assert len(lines) == 1 and lines[0].startswith("error:"), result.output
    for phrase in phrases:
        assert phrase in lines[0], (phrase, lines[0])
    return lines[0]


def formats(*names: str) -> list:
    """Format names as parameters; xrk's skip where libxrk has no wheel."""
    return [pytest.param(n, marks=needs_libxrk) if n == "xrk" else n for n in names]


FMTS = formats("mcap", "parquet", "csv", "mdf", "xrk")
SPEED = {"vFront": (_t(), 100.0 + _t(), "km/h")}


@pytest.mark.parametrize("fmt", FMTS)
def test_unknown_unit_every_format(fmt: str, tmp_path: Path,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_any(fmt, tmp_path / "u", {"vFront": (_t(), _t(), "blorps")}, monkeypatch)
    cli_error([str(path)], str(path), "channel 'vFront'", "unknown unit 'blorps'", "km/h")


@pytest.mark.parametrize("fmt", FMTS)
def test_missing_channel_every_format(fmt: str, tmp_path: Path,
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_any(fmt, tmp_path / "m", SPEED, monkeypatch)
    cli_error([str(path), "--require", "brake_pressure_front"],
              "channel 'brake_pressure_front'", "required channel is missing", "vFront")


@pytest.mark.parametrize("fmt", FMTS)
def test_single_sample_channel_every_format(fmt: str, tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    chans = {**SPEED, "pBrakeF": (np.array([1.0]), np.array([3.0]), "bar")}
    path = write_any(fmt, tmp_path / "one", chans, monkeypatch)
    cli_error([str(path), "--require", "brake_pressure_front"],
              "channel 'brake_pressure_front'", "holds a single sample (300000 Pa)")


# CSV and MCAP JSON have no way to write an infinite number: NaN (empty / null) only.
NON_FINITE = [pytest.param(f, bad, marks=needs_libxrk) if f == "xrk" else (f, bad)
              for bad, names in ((np.nan, ("mcap", "parquet", "csv", "mdf", "xrk")),
                                 (np.inf, ("parquet", "mdf", "xrk"))) for f in names]


@pytest.mark.parametrize(("fmt", "bad"), NON_FINITE)
def test_all_non_finite_channel_every_format(fmt: str, bad: float, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    chans = {**SPEED, "pBrakeF": (_t(), np.full(200, bad), "bar")}
    path = write_any(fmt, tmp_path / "null", chans, monkeypatch)
    session = load_session(path)
    assert not session.has("brake_pressure_front")
    cli_error([str(path), "--require", "brake_pressure_front"],
              "channel 'brake_pressure_front'", "holds no finite sample",
              "cannot carry the computation")


@pytest.mark.parametrize("fmt", ["mcap", "parquet", "mdf"])
def test_truncated_or_corrupt_file_every_format(fmt: str, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_any(fmt, tmp_path / "cut", SPEED, monkeypatch)
    data = path.read_bytes()
    path.write_bytes(data[:60])
    cli_error([str(path)], str(path))
    path.write_bytes(np.random.default_rng(0).bytes(len(data)))
    cli_error([str(path)], str(path))


def test_truncated_csv_keeps_its_complete_rows(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_any("csv", tmp_path / "cut", SPEED, monkeypatch)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    result = CliRunner().invoke(app, ["inspect", str(path), "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    assert 0 < info["channels"][0]["samples"] < 200


@pytest.mark.parametrize("fmt", FMTS)
def test_inspect_shows_format_and_sources(fmt: str, tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    chans: dict[str, tuple[np.ndarray, np.ndarray, str]] = {
        **SPEED, "rideHeight[/b]": (_t(), _t(), "V")}
    path = write_any(fmt, tmp_path / "show", chans, monkeypatch)
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 0, result.output
    name = {"mcap": "MCAP", "parquet": "Parquet", "csv": "CSV", "mdf": "MDF 4.10",
            "xrk": "AiM XRK"}[fmt]
    assert f"({name})" in result.output
    assert "vFront" in result.output and "rideHeight[/b]" in result.output
    as_json = json.loads(CliRunner().invoke(app, ["inspect", str(path), "--json"]).output)
    assert as_json["format"] == name
    assert set(as_json["sources"]) >= {"vFront", "rideHeight[/b]"}

