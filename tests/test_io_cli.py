"""``brakethermo inspect``: the JSON summary, and one clear line + exit 1 for every bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from test_io_hardening import one_line_error
from test_io_roundtrip import CHANNELS, FACTS, write_csv, write_mcap
from typer.testing import CliRunner

from brakethermo.cli import app

REFERENCE_MCAP = next(
    (p for p in (Path(__file__).resolve().parents[2] / "shared" / "reference" / "mcap",
                 Path("/work/shared/reference/mcap")) if p.is_dir()),
    Path(__file__).resolve().parents[2] / "shared" / "reference" / "mcap",
)
needs_reference = pytest.mark.skipif(
    not REFERENCE_MCAP.is_dir(),
    reason=f"third-party reference MCAP files not present at {REFERENCE_MCAP}",
)


def run(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, ["inspect", *args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.output


def assert_user_error(args: list[str], *phrases: str) -> str:
    return one_line_error(["inspect", *args], *phrases)


def test_inspect_json(tmp_path: Path) -> None:
    path = write_mcap(tmp_path / "s.mcap", grouped=True, epoch=True)
    code, output = run(str(path), "--json")
    assert code == 0, output
    info = json.loads(output)
    names = {c["name"]: c for c in info["channels"]}
    assert set(names) == {c for _, _, c in CHANNELS.values() if c}
    speed = names["speed"]
    assert speed["source"] == "vFront" and speed["unit"] == "km/h"
    assert speed["rate_hz"] == pytest.approx(100.0) and speed["samples"] == 4001
    assert speed["gaps"] == []
    assert names["disc_temp_spot2"]["source"] == "disc_temp.spot2"
    assert [(lap["lap"], lap["start_s"], lap["duration_s"]) for lap in info["laps"]] == [
        (0, 0.0, 5.0), (1, 5.0, 20.0), (2, 25.0, 15.0)]
    assert info["session"] == FACTS
    assert info["unmapped"] == ["rideHeight"]


def test_inspect_rich_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "160")
    code, output = run(str(write_csv(tmp_path / "s.csv")))
    assert code == 0, output
    for text in ("brake_pressure_front", "pBrakeF", "rpm", "out-lap", "0:20.000"):
        assert text in output


def test_inspect_reports_gaps_and_truncation(tmp_path: Path) -> None:
    full = write_mcap(tmp_path / "full.mcap", chunk_size=8_192)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full.read_bytes()[: int(full.stat().st_size * 0.7)])
    code, output = run(str(cut), "--json")
    assert code == 0
    warnings = json.loads(output)["warnings"]
    assert any("truncated" in w for w in warnings)


def test_missing_required_channel(tmp_path: Path) -> None:
    path = write_mcap(tmp_path / "s.mcap")
    line = assert_user_error([str(path), "--require", "speed", "--require", "wheel_omega"],
                             "channel 'wheel_omega'", "tried: wheel_omega, wWheel",
                             "the file has: vFront", "--aliases")
    assert str(path) in line
    # a name that is no channel at all is said so (it read "missing, tried: bogus")
    assert_user_error([str(path), "--require", "bogus"], "not a canonical channel")


def test_missing_file_directory_unknown_extension_empty(tmp_path: Path) -> None:
    assert_user_error([str(tmp_path / "nope.mcap")], "file not found")
    assert_user_error([str(tmp_path)], "is not a file")
    other = tmp_path / "s.txt"
    other.write_text("time,a\n0,1\n")
    assert_user_error([str(other)], "unknown session file type '.txt'")
    for ext in ("mcap", "parquet", "csv"):
        empty = tmp_path / f"empty.{ext}"
        empty.write_bytes(b"")
        assert_user_error([str(empty)], "empty")


def test_unreadable_parquet_and_csv(tmp_path: Path) -> None:
    bad = tmp_path / "s.parquet"
    bad.write_bytes(b"definitely not parquet" * 10)
    assert_user_error([str(bad)], "not a readable Parquet file")
    header_only = tmp_path / "h.csv"
    header_only.write_text("time [s],vFront [km/h]\n")
    assert_user_error([str(header_only)], "at least one channel and one data row")


@needs_reference
def test_bad_magic() -> None:
    assert_user_error([str(REFERENCE_MCAP / "keelson_bad_magic.mcap")], "not a valid MCAP file")


@needs_reference
def test_mcap_without_channels() -> None:
    assert_user_error([str(REFERENCE_MCAP / "keelson_empty.mcap")], "no channels")


@needs_reference
def test_cdr_encoding_not_supported() -> None:
    assert_user_error([str(REFERENCE_MCAP / "mcap_arrow_cdr.mcap")],
                      "encoding 'cdr' is not supported", "only JSON")


def test_unknown_unit(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    path.write_text("time [s],vFront [blorps]\n0,1\n0.1,2\n")
    assert_user_error([str(path)], str(path), "channel 'vFront'",
                      "unknown unit 'blorps'")


def test_unit_of_wrong_kind(tmp_path: Path) -> None:
    path = write_mcap(tmp_path / "s.mcap", channels={"vFront": (100.0, "bar", "speed")})
    assert_user_error([str(path)], "channel 'vFront'", "pressure unit")


def test_non_numeric_value_csv(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    path.write_text("time,pBrakeF [bar]\n0,1.5\n0.1,2.5\n0.2,oops\n0.3,4\n")
    assert_user_error([str(path)], "channel 'pBrakeF'", "'oops'", "data row 3")


def test_non_numeric_value_mcap(tmp_path: Path) -> None:
    path = write_mcap(tmp_path / "s.mcap", channels={"pBrakeF": (10.0, "bar", "")},
                      payload='{{"value": "{v:.1f} bar"}}')
    assert_user_error([str(path)], "channel 'pBrakeF'", "non-numeric value")


def test_text_column_is_ignored_mixed_column_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    path.write_text("time,vFront [km/h],comment\n0,1,pit exit\n0.1,2,\n0.2,3,box\n")
    code, output = run(str(path), "--json")
    assert code == 0, output
    assert "column 'comment' holds text" in json.loads(output)["warnings"][0]


def test_non_numeric_value_parquet(tmp_path: Path) -> None:
    path = tmp_path / "s.parquet"
    pq.write_table(pa.table({"time": [0.0, 0.1, 0.2], "pBrakeF": ["1.0", "2.0", "x"]}), path)
    assert_user_error([str(path)], "channel 'pBrakeF'", "'x'", "row 3")
    no_time = tmp_path / "t.parquet"
    pq.write_table(pa.table({"t": [0.0, 0.1], "pBrakeF": [1.0, 2.0]}), no_time)
    assert_user_error([str(no_time)], "no 'time' column", "t, pBrakeF")


def test_duplicate_timestamps(tmp_path: Path) -> None:
    path = tmp_path / "s.csv"
    path.write_text("time,vFront [km/h]\n0,1\n0.1,2\n0.1,3\n0.2,4\n")
    assert_user_error([str(path)], "channel 'vFront'", "1 duplicate timestamp(s)", "t = 0.1")


def test_truncated_mcap_without_usable_data(tmp_path: Path) -> None:
    full = write_mcap(tmp_path / "full.mcap", chunk_size=1 << 20)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full.read_bytes()[:200])
    assert_user_error([str(cut)], "truncated")


def test_invalid_alias_file(tmp_path: Path) -> None:
    session = write_csv(tmp_path / "s.csv")
    bad = tmp_path / "bad.toml"
    bad.write_text("[aliases\nspeed = 3")
    assert_user_error([str(session), "--aliases", str(bad)], "invalid TOML")
    wrong = tmp_path / "wrong.toml"
    wrong.write_text('[aliases]\nsped = ["vFront"]\n')
    assert_user_error([str(session), "--aliases", str(wrong)],
                      "key 'aliases.sped': expected a canonical")
    shape = tmp_path / "shape.toml"
    shape.write_text("[aliases]\nspeed = [1, 2]\n")
    assert_user_error([str(session), "--aliases", str(shape)], "list of non-empty texts")


def test_inspect_fits_80_columns_with_names_whole(tmp_path, monkeypatch) -> None:
    """At 80 columns every line fits and the logged topic names stay whole (a source
    folded into 'disc_te / mp.spot / 1' read as three names)."""
    from brakethermo.sim.session import SimConfig, simulate, write_simulation

    path = write_simulation(simulate(SimConfig(laps=1, sensor="multi", seed=4441)),
                            tmp_path / "grouped.mcap", grouped=True)[0]
    from brakethermo.cli import _app

    monkeypatch.setattr(_app.console, "_width", 80)  # read from COLUMNS at import
    result = CliRunner().invoke(app, ["inspect", str(path)])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert max(len(line) for line in lines) <= 80
    row = next(line for line in lines if line.startswith("disc_temp_spot1"))
    assert "disc_temp.spot1" in row, result.output


def test_inspect_says_the_rate_a_rig_log_is_logged_at(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """A 1 kHz tyre log was described as "6167 points at 10 Hz" (the disc grid) only."""
    from brakethermo.sim.tyre_rig import simulate_tyre_rig, write_tyre_simulation

    monkeypatch.setenv("COLUMNS", "200")
    path = write_tyre_simulation(simulate_tyre_rig(seed=3), tmp_path / "ty.mcap")[0]
    code, output = run(str(path))
    assert code == 0, output
    said = " ".join(output.replace("│", " ").split())  # a wrapped table cell
    assert "the disc pipelines' grid; logged at up to 1000 Hz, the rate the rig commands" in said


def test_inspect_says_a_disc_sessions_fast_channels_without_the_rig_commands() -> None:
    """A disc race's 100 Hz wheel speed read "the rate the rig commands read" (review):
    the rig commands read no disc session."""
    code, output = run(str(Path(__file__).resolve().parents[1] / "sample_sessions"
                           / "mugello_race_single.parquet"))
    assert code == 0, output
    said = " ".join(output.replace("│", " ").split())
    assert "logged at up to 100 Hz" in said and "rig commands" not in said
