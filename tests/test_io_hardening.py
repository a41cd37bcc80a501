"""Issue 12, logs that real loggers write: clock jumps and integer time units, channels that
cannot carry a computation, beacons that bounce, damaged MCAP chunks, European CSV
exports, and user text that must never be read as console markup."""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import typer
from mcap.writer import CompressionType
from test_io_roundtrip import CHANNELS, EPOCH_NS, write_csv, write_mcap
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.cli._app import _UserErrorGroup
from brakethermo.errors import DataError
from brakethermo.io import load_session
from brakethermo.io.laps import validate_beacons
from brakethermo.io.session import Session

RUN = CliRunner()


def one_line_error(args: list[str], *phrases: str) -> str:
    result = RUN.invoke(app, args)
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert result.exit_code == 1, result.output
    assert len(lines) == 1 and lines[0].startswith("error:"), result.output
    for phrase in phrases:
        assert phrase in lines[0], (phrase, lines[0])
    return lines[0]


def parquet(path: Path, time: pa.Array, values: dict[str, np.ndarray],
            time_unit: str | None = None) -> Path:
    fields = [pa.field("time", time.type, metadata={"unit": time_unit} if time_unit else None)]
    arrays = [time]
    for name, v in values.items():
        fields.append(pa.field(name, pa.float64(), metadata={"unit": "km/h"}))
        arrays.append(pa.array(v, pa.float64(), mask=np.isnan(v)))
    pq.write_table(pa.Table.from_arrays(arrays, schema=pa.schema(fields)), path)
    return path


# -- 1. wild timestamps, integer time units, implausible spans ------------------------------


@pytest.mark.parametrize("jump_s", [8.6e5, 1.0e9, -1.7e9])
def test_isolated_clock_jump_is_dropped_with_a_warning(jump_s: float, tmp_path: Path) -> None:
    n = 600
    t = np.arange(n) * 0.1
    t[400] += jump_s  # one sample's clock glitched (1.0e9 s: a 31-year jump)
    if jump_s < 0:
        t = t + 1.8e9  # an epoch log whose glitched sample reads ~0
    time_arr = pa.array(np.round(t * 1e9).astype(np.int64), pa.timestamp("ns"))
    session = load_session(parquet(tmp_path / "s.parquet", time_arr, {"vFront": 100.0 + t}))
    assert len(session.frame) == 600  # 59.9 s at 10 Hz, not months of grid
    warning = next(w for w in session.warnings if "isolated" in w)
    assert "dropped 1 isolated sample" in warning and "'vFront' (1)" in warning
    assert ("after" if jump_s > 0 else "before") in warning
    if jump_s < 0:
        assert session.start_epoch_s == pytest.approx(1.8e9)


def test_late_outlier_in_mcap_keeps_the_session_length(tmp_path: Path) -> None:
    path = write_mcap(tmp_path / "s.mcap", epoch=True,
                      channels={"vFront": (100.0, "km/h", "speed")})
    good = load_session(path)
    from mcap.writer import Writer

    bad = tmp_path / "late.mcap"
    with bad.open("wb") as fh:  # the same log plus one sample 8.6e5 s late
        w = Writer(fh)
        w.start()
        sid = w.register_schema("v", "jsonschema", b"{}")
        cid = w.register_channel("vFront", "json", sid, {"unit": "km/h"})
        for k in range(4001):
            w.add_message(cid, EPOCH_NS + k * 10_000_000, b'{"value": 100.0}', 0)
        w.add_message(cid, EPOCH_NS + int(8.6e14), b'{"value": 100.0}', 0)
        w.finish()
    session = load_session(bad)
    assert len(session.frame) == len(good.frame)
    assert any("dropped 1 isolated sample" in w for w in session.warnings)


def test_implausible_span_is_refused_before_allocating(tmp_path: Path) -> None:
    t = np.concatenate([np.arange(500) * 0.1, 40 * 86400.0 + np.arange(500) * 0.1])
    path = parquet(tmp_path / "s.parquet", pa.array(t), {"vFront": np.ones(t.size)})
    with pytest.raises(DataError, match=r"span 40\.0 days, longer than any session"):
        load_session(path)
    one_line_error(["inspect", str(path)], "longer than any session")


def test_grid_too_large_for_the_rate_is_refused(tmp_path: Path) -> None:
    path = parquet(tmp_path / "s.parquet", pa.array(np.arange(1000) * 1.0),
                   {"vFront": np.ones(1000)})
    with pytest.raises(DataError, match="grid points"):
        load_session(path, rate_hz=1e6)


def test_milliseconds_labelled_seconds_are_refused_before_any_work(tmp_path: Path) -> None:
    """A 200 Hz log whose time column is in ms but says s: every step 5 s, 3 days long."""
    path = parquet(tmp_path / "s.parquet", pa.array(np.arange(5000) * 5.0),
                   {"vFront": np.ones(5000)})
    with pytest.raises(DataError, match=r"milliseconds labelled seconds.*200 Hz"):
        load_session(path, rate_hz=None)


@pytest.mark.parametrize(("unit", "scale"), [("s", 1), ("ms", 10**3), ("µs", 10**6),
                                             ("ns", 10**9)])
def test_integer_parquet_time_unit_is_inferred(unit: str, scale: int, tmp_path: Path) -> None:
    step = 1 if unit == "s" else scale // 10  # 1 Hz in whole seconds, else 10 Hz
    t = np.arange(0, 2500 * scale + 1, step, dtype=np.int64)
    if unit != "s":
        t += EPOCH_NS // 10**9 * scale  # absolute time, as loggers write it
    v = np.linspace(0.0, 1.0, t.size)
    session = load_session(parquet(tmp_path / "s.parquet", pa.array(t), {"vFront": v}))
    assert session.time[-1] == pytest.approx(2500.0)
    notes = [w for w in session.warnings if "holds integers" in w]
    assert (notes == []) if unit == "s" else (f"assumed {unit}" in notes[0])


def test_time_unit_metadata_and_csv_integer_ms(tmp_path: Path) -> None:
    t = np.arange(0.0, 60_001.0, 10.0)
    session = load_session(parquet(tmp_path / "s.parquet", pa.array(t), {"vFront": t * 0},
                                   time_unit="ms"))
    assert session.time[-1] == pytest.approx(60.0)
    csv = tmp_path / "s.csv"
    csv.write_text("time,vFront [km/h]\n" + "".join(f"{k * 20},{k}\n" for k in range(3001)))
    session = load_session(csv)
    assert session.time[-1] == pytest.approx(60.0)
    assert any("assumed ms" in w for w in session.warnings)


# -- 2. channels that cannot carry the computation; beacons ---------------------------------


def test_estimate_refuses_a_pressure_channel_without_samples(tmp_path: Path) -> None:
    t = np.arange(0, 120.0, 0.1)
    rows = "".join(f"{x:.1f},{200 + 50 * np.sin(x / 10):.3f},,{400 + x:.2f}\n" for x in t)
    path = tmp_path / "race.csv"
    path.write_text("time [s],vFront [km/h],pBrakeF [bar],TDisc [degC]\n" + rows)
    one_line_error(["estimate", str(path), "--out", str(tmp_path / "out"), "--ambient", "20",
                    "--no-report"],
                   "channel 'brake_pressure_front'", "'pBrakeF' holds no finite sample",
                   "cannot carry the computation")
    assert not (tmp_path / "out" / "race" / "estimate.parquet").exists()


def test_non_finite_samples_are_dropped_and_counted(tmp_path: Path) -> None:
    t = np.arange(100) * 0.1
    v = 100.0 + t
    v[[10, 20, 30]] = [np.inf, -np.inf, np.nan]
    session = load_session(parquet(tmp_path / "s.parquet", pa.array(t), {"vFront": v}))
    assert session.channels["speed"].samples == 97  # the NaN is a null: no sample at all
    assert any("2 non-finite sample(s)" in w for w in session.warnings)
    assert np.isfinite(session.values("speed")).all()


def laps_of(tmp_path: Path, beacons: list[tuple[float, float]]) -> tuple[list, tuple]:
    t = np.arange(0, 800.0, 0.5)
    rows = {round(x, 1): f"{x:.1f},{100.0:.1f}," for x in t}
    for tb, value in beacons:
        rows[round(tb, 1)] = f"{tb:.1f},100.0,{value!r}"
    path = tmp_path / "laps.csv"
    path.write_text("time,vFront [km/h],lap_beacon\n" + "\n".join(rows[k] for k in sorted(rows)))
    session = load_session(path)
    return [(lap.lap, round(lap.start_s, 1)) for lap in session.laps], session.warnings


def test_beacon_stepping_back_is_renumbered(tmp_path: Path) -> None:
    laps, warnings = laps_of(tmp_path, [(10.0 + 115 * k, v) for k, v in
                                        enumerate([0, 1, 2, 3, 2, 5])])
    assert laps == [(0, 0.0), (1, 125.0), (2, 240.0), (3, 355.0), (4, 470.0), (5, 585.0)]
    note = next(w for w in warnings if "renumbered" in w)
    assert "0, 1, 2, 3, 2, 5" in note and "2 -> 4" in note


def test_beacon_garbage_value_and_bounce(tmp_path: Path) -> None:
    beacons = [(10.0, 1), (125.0, 2), (125.5, 2), (240.0, 1e20), (355.0, 4)]
    laps, warnings = laps_of(tmp_path, beacons)
    assert [n for n, _ in laps] == [0, 1, 2, 3, 4]
    assert [s for _, s in laps] == [0.0, 10.0, 125.0, 240.0, 355.0]
    assert any("beacon bounces" in w and "125.50" in w for w in warnings)
    assert any("1e+20 -> 3" in w for w in warnings)


def test_laps_from_a_lap_distance_that_resets_at_the_line(tmp_path: Path) -> None:
    """A race logged without its beacon but with the lap distance became one 13-minute
    out-lap (an independent generator's race: 0.144 -> 0.261x of the single-spot baseline,
    the race unable to decide its online effects, no word). The distance's resets give
    the laps, with a warning; a cumulative odometer gives none."""
    from brakethermo.io.laps import beacons_from_distance

    t = np.arange(0.0, 590.0, 0.1)
    lap_s = 115.0
    d = np.where(t < 100.0, 40.0 * t, 40.0 * ((t - 100.0) % lap_s))  # the line at 100 s
    d += np.random.default_rng(0).normal(0.0, 0.5, t.size)
    np.testing.assert_allclose(beacons_from_distance(t, d), [100.0, 215.0, 330.0, 445.0,
                                                             560.0], atol=0.11)
    assert beacons_from_distance(t, 40.0 * t).size == 0  # an odometer never resets
    rows = "\n".join(f"{x:.1f},100.0,{v:.2f}" for x, v in zip(t, d, strict=True))
    path = tmp_path / "nobeacon.csv"
    path.write_text("time,vFront [km/h],distance [m]\n" + rows)
    session = load_session(path)
    assert [lap.lap for lap in session.laps] == [0, 1, 2, 3, 4, 5]
    assert session.laps[1].start_s == pytest.approx(100.0, abs=0.11)
    assert any("no lap_beacon channel: 5 line crossing(s)" in w for w in session.warnings)


def test_beacon_checks_directly() -> None:
    t = np.array([0.0, 100.0, 200.0, 300.0, 400.0])
    _, vb, notes = validate_beacons(t, np.array([0.0, 1.0, 2.0, 3.0, 4.0]))
    assert notes == [] and vb.tolist() == [0, 1, 2, 3, 4]
    _, vb, notes = validate_beacons(t, np.array([1.0, 2.0, 4.0, 5.0, 6.0]))
    assert vb.tolist() == [1, 2, 4, 5, 6] and "no crossing for lap(s) 3" in notes[0]
    _, _, notes = validate_beacons(np.array([0.0, 100, 200, 300, 520, 620]),
                                   np.arange(6.0))
    assert "a missed beacon?" in notes[0] and "3 (220.0 s)" in notes[0]
    with pytest.raises(DataError, match=r"is not a lap number.*really the lap beacon"):
        validate_beacons(t[:3], np.array([0.5, 1.5, 2.0]), channel="dist")


# -- 3. damaged MCAP chunks ----------------------------------------------------------------


FEW = {name: CHANNELS[name] for name in ("vFront", "TDiscFL_3")}


def chunk_offsets(data: bytes) -> list[tuple[int, int]]:
    """(offset, record length) of every Chunk record, walking the records independently."""
    out, pos = [], 8
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        if opcode == 0x06:
            out.append((pos, length))
        if opcode == 0x0F:
            break
        pos += 9 + length
    return out


@pytest.mark.parametrize("index", [True, False], ids=["indexed", "no-index"])
def test_one_damaged_zstd_chunk_loses_only_its_time_range(index: bool, tmp_path: Path) -> None:
    full = write_mcap(tmp_path / "full.mcap", chunk_size=8_192, index=index, channels=FEW)
    data = bytearray(full.read_bytes())
    chunks = chunk_offsets(bytes(data))
    assert len(chunks) > 8
    pos, length = chunks[len(chunks) // 3]
    for k in range(40):  # a burst of bit rot inside the compressed records
        data[pos + 9 + length // 2 + k] ^= 0x5A
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    session, ref = load_session(bad), load_session(full)
    warning = next(w for w in session.warnings if "corrupt chunk" in w)
    assert f"at byte {pos}" in warning and "messages from t = " in warning
    match = re.search(r"messages from t = ([\d.]+) s to ([\d.]+) s are lost", warning)
    assert match is not None, warning
    lost = [float(match[1]), float(match[2])]
    assert 0 < lost[0] < lost[1] < 40
    t = session.time
    away = (t < lost[0] - 1.0) | (t > lost[1] + 1.0)
    assert away.mean() > 0.6  # every chunk after the damaged one is still read
    for col in ("speed", "disc_temp_spot3"):
        np.testing.assert_allclose(session.frame[col].to_numpy()[away],
                                   ref.frame[col].to_numpy()[away], rtol=1e-9, err_msg=col)


def test_bit_rot_in_an_uncompressed_chunk_is_caught_by_its_crc(tmp_path: Path) -> None:
    full = write_mcap(tmp_path / "full.mcap", chunk_size=8_192, channels=FEW,
                      compression=CompressionType.NONE)
    data = bytearray(full.read_bytes())
    pos, length = chunk_offsets(bytes(data))[3]
    at = data.index(b'"value": ', pos, pos + 9 + length) + len(b'"value": ')
    data[at] = ord("1") + (data[at] - ord("0")) % 8  # e.g. 405 degC would read 505 degC
    bad = tmp_path / "rot.mcap"
    bad.write_bytes(bytes(data))
    session = load_session(bad)
    assert any("corrupt chunk" in w and "CRC mismatch" in w for w in session.warnings)
    one_line = RUN.invoke(app, ["inspect", str(bad)])
    assert one_line.exit_code == 0 and "corrupt chunk" in one_line.output
    assert "not valid JSON" not in one_line.output


# -- 4. CSV dialects and encodings --------------------------------------------------------


@pytest.fixture(scope="module")
def comma_csv(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Session]:
    path = write_csv(tmp_path_factory.mktemp("csv") / "ref.csv")
    return path, load_session(path)


@pytest.mark.parametrize(("sep", "dec"), [(";", ","), ("\t", ","), ("\t", "."), ("|", ".")])
def test_european_csv_exports(sep: str, dec: str, tmp_path: Path,
                              comma_csv: tuple[Path, Session]) -> None:
    comma, ref = comma_csv
    lines = comma.read_text().splitlines()
    out = []
    for line in lines:
        cells = line.split(",")
        out.append(sep.join(c.replace(".", dec) if dec == "," else c for c in cells))
    path = tmp_path / "eu.csv"
    path.write_text("\n".join(out) + "\n", encoding="utf-8-sig" if sep == ";" else "utf-8")
    session = load_session(path)
    np.testing.assert_allclose(session.frame.to_numpy(dtype=float),
                               ref.frame.to_numpy(dtype=float), rtol=1e-12)


def test_csv_encodings_get_a_message(tmp_path: Path) -> None:
    text = "time [s];TDisc [°C]\n0;1,5\n0,1;2,5\n"
    cp = tmp_path / "cp1252.csv"
    cp.write_bytes(text.encode("cp1252"))
    one_line_error(["inspect", str(cp)], "not UTF-8", "byte 0xb0 on line 1", "Windows-1252",
                   "save it as UTF-8")
    u16 = tmp_path / "utf16.csv"
    u16.write_bytes(text.encode("utf-16"))
    one_line_error(["inspect", str(u16)], "UTF-16", "save it as UTF-8")
    one = tmp_path / "one.csv"
    one.write_text("time vFront\n0 1\n")
    one_line_error(["inspect", str(one)], "cannot find the column separator", "'time vFront'")


# -- 5. user text is never console markup ---------------------------------------------------


def test_markup_in_units_and_names_is_shown_as_written(tmp_path: Path) -> None:
    path = write_mcap(tmp_path / "s.mcap", channels={"vFront": (100.0, "[km/h]", "speed")})
    one_line_error(["inspect", str(path)], "unknown unit '[km/h]'", "channel 'vFront'")
    csv = tmp_path / "b.csv"
    csv.write_text("time,vFront [/b]\n0,1\n0.1,2\n")
    one_line_error(["inspect", str(csv)], "unknown unit '/b'")
    one_line_error(["estimate", str(csv), "--out", str(tmp_path / "o")], "unknown unit '/b'")
    odd = tmp_path / "odd[bold].csv"
    odd.write_text("time,vFront [km/h],x[/b] [V],[bold]y[/bold] [V]\n0,1,2,3\n0.1,2,3,4\n")
    result = RUN.invoke(app, ["inspect", str(odd)])
    assert result.exit_code == 0, result.output
    assert "odd[bold].csv" in result.output and "x[/b]" in result.output
    assert "[bold]y[/bold]" in result.output
    one_line_error(["inspect", str(odd), "--require", "disc_temp"], "the file has: vFront, x[/b]")


def test_numpy_runtime_warnings_do_not_reach_the_user() -> None:
    probe = typer.Typer(cls=_UserErrorGroup)

    @probe.command()
    def mean_of_nothing() -> None:
        typer.echo(f"value {np.nanmean(np.full(3, np.nan))} {np.log(0.0)}")

    @probe.command()
    def other() -> None:  # two commands: Typer keeps the group
        """Unused."""

    result = RUN.invoke(probe, ["mean-of-nothing"])
    assert result.exit_code == 0
    assert result.output.strip() == "value nan -inf"
    assert "RuntimeWarning" not in result.output


def test_damaged_parquet_row_group_is_skipped_with_a_warning(tmp_path: Path) -> None:
    t = np.arange(4000) * 0.01
    table = pa.table({"time": t, "vFront": 100.0 + t})
    path = tmp_path / "s.parquet"
    pq.write_table(table, path, row_group_size=1000, write_page_checksum=True,
                   compression="none")
    data = bytearray(path.read_bytes())
    meta = pq.ParquetFile(path).metadata
    col = meta.row_group(2).column(1)  # vFront of rows 2001-3000
    at = (col.dictionary_page_offset or col.data_page_offset) + col.total_compressed_size // 2
    data[at : at + 16] = bytes(16)
    path.write_bytes(bytes(data))
    session = load_session(path)
    warning = next(w for w in session.warnings if "corrupt row group" in w)
    assert "row group 3 of 4 (rows 2001-3000)" in warning
    assert session.channels["speed"].samples == 3000
    assert session.channels["speed"].gaps  # the lost 10 s show as a reported gap


# -- absolute (epoch) float times -------------------------------------------------------------


def _epoch_copy(src: Path, dst: Path, *, ns: bool = False) -> Path:
    """``src`` with its time column as epoch seconds (float64 1.7e9 + t), or as
    timestamp[ns] of the same instants, the rest as written."""
    table = pq.read_table(src)
    t = table.column("time").to_numpy()
    i = table.schema.get_field_index("time")
    if ns:
        ticks = (np.round(t * 1e9).astype(np.int64) + 1_700_000_000 * 10**9)
        col, kind = pa.array(ticks, pa.timestamp("ns")), pa.timestamp("ns")
    else:
        col, kind = pa.array(1.7e9 + t, pa.float64()), pa.float64()
    field = table.schema.field(i).with_type(kind)
    pq.write_table(table.set_column(i, field, col), dst)
    return dst


def test_epoch_float_times_give_the_logged_rate_on_a_rig_session(tmp_path: Path) -> None:
    """A 1 kHz tyre session with float64 epoch seconds read at 1000.07 Hz, and its noise
    0.0218 for 0.0308: the absolute times' 2.4e-7 s resolution leaked into the rate and
    the grid. Now the same figures as its timestamp[ns] copy."""
    from brakethermo.pipelines.mu_slip import mu_slip, summary
    from brakethermo.sim.tyre_rig import simulate_tyre_rig, write_tyre_simulation

    src = write_tyre_simulation(simulate_tyre_rig("wet", seed=4), tmp_path / "t.parquet")[0]
    flo = _epoch_copy(src, tmp_path / "abs.parquet")
    ns = _epoch_copy(src, tmp_path / "absns.parquet", ns=True)
    assert load_session(flo, rate_hz=None).rate_hz == pytest.approx(1000.0, abs=1e-6)
    a, b = summary(mu_slip(flo)), summary(mu_slip(ns))
    assert a["noise_std_mu"] == pytest.approx(b["noise_std_mu"], rel=1e-6)


def test_epoch_float_times_keep_a_disc_session_as_logged(tmp_path: Path) -> None:
    """The same on a disc session: its native rates and its grid's values are those of
    the session logged from 0 s."""
    from _synth_race import write_session_parquet

    src = write_session_parquet(tmp_path / "race.parquet", 1, seed=3)
    flo = _epoch_copy(src, tmp_path / "race_abs.parquet")
    s0, s1 = load_session(src), load_session(flo)
    for name, info in s0.channels.items():
        assert s1.channels[name].rate_hz == pytest.approx(info.rate_hz, rel=1e-9), name
    assert s1.frame.shape == s0.frame.shape
    np.testing.assert_allclose(s1.frame.to_numpy(float), s0.frame.to_numpy(float),
                               rtol=1e-9, atol=1e-9)
    assert s1.start_epoch_s == pytest.approx(1.7e9)
