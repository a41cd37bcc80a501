"""Mislabelled units and frozen sensors in a disc session: a clear line naming the channel
and the likely unit, or a loud warning, never a silent impossible estimate."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.errors import DataError

runner = CliRunner()


def _mutate(src: Path, dst: Path, column_prefix: str, fn) -> Path:
    table = pq.read_table(src)
    cols = []
    for name in table.column_names:
        col = table.column(name)
        if name.startswith(column_prefix):
            arr = col.to_numpy(zero_copy_only=False).astype(float)
            col = pa.array(fn(arr), type=pa.float64())
        cols.append(col)
    out = pa.Table.from_arrays(cols, schema=table.schema)
    pq.write_table(out, dst)
    return dst


def _estimate(path: Path, tmp: Path):
    return runner.invoke(app, ["estimate", str(path), "--out", str(tmp / "o"), "--no-report",
                               "--no-smoother", "--json"])


def test_wheel_speed_in_rpm_labelled_rad_s_is_named(sim_race_session, tmp_path: Path) -> None:
    bad = _mutate(sim_race_session[0], tmp_path / "rpm.parquet", "wheel_speed_front",
                  lambda v: v * 60.0 / (2 * np.pi))
    res = _estimate(bad, tmp_path)
    assert res.exit_code == 1, res.output
    assert "wheel_speed_front" in res.output and "rpm labelled rad/s" in res.output
    assert "Traceback" not in res.output


def test_a_frozen_pyrometer_is_refused(sim_race_session, tmp_path: Path) -> None:
    bad = _mutate(sim_race_session[0], tmp_path / "stuck.parquet", "disc_temp",
                  lambda v: np.where(np.isfinite(v), 300.0, v))
    res = _estimate(bad, tmp_path)
    assert res.exit_code == 1, res.output
    assert "stuck or frozen" in res.output and "Traceback" not in res.output


def test_a_pyrometer_in_kelvin_labelled_celsius_is_said_loudly(sim_race_session,
                                                               tmp_path: Path) -> None:
    # a kelvin pyrometer has no floor at 100 "degC": it logs the cold disc at rest too
    bad = _mutate(sim_race_session[0], tmp_path / "kelvin.parquet", "disc_temp",
                  lambda v: np.where(np.isfinite(v), v, 23.0) + 273.15)
    res = _estimate(bad, tmp_path)
    if res.exit_code == 1:  # the filter may also find the readings impossible
        assert "Traceback" not in res.output
        return
    warnings = json.loads(res.stdout)["run"]["warnings"]
    assert any("kelvin" in w for w in warnings), warnings


@pytest.mark.parametrize("factor", [1.0])
def test_the_clean_session_passes_every_check(sim_race_session, tmp_path: Path,
                                              factor: float) -> None:
    res = _estimate(sim_race_session[0], tmp_path)
    assert res.exit_code == 0, res.output
    warnings = json.loads(res.stdout)["run"]["warnings"]
    assert not any("kelvin" in w or "IMPLAUSIBLE" in w for w in warnings)


SAMPLE_CSV = Path(__file__).parents[1] / "sample_sessions" / "tight_test_multi.csv"


def _celsius_labelled_kelvin(dst: Path) -> Path:
    """The shipped multi-spot CSV with its four pyrometers' unit cells saying K."""
    lines = SAMPLE_CSV.read_text().splitlines(keepends=True)
    head = lines[0].replace("[degC],", "[K],", 4)
    assert head.count("[K]") == 4
    dst.write_text(head + "".join(lines[1:]))
    return dst


@pytest.mark.parametrize("command", ["estimate", "identify-h", "diagnose"])
def test_degc_labelled_kelvin_is_refused_by_every_disc_command(tmp_path: Path,
                                                               command: str) -> None:
    # the readings become -173..+510 degC with the air at 26 degC: diagnose gave a verdict
    bad = _celsius_labelled_kelvin(tmp_path / "as_kelvin.csv")
    res = runner.invoke(app, [command, str(bad), "--out", str(tmp_path / "o")])
    text = " ".join(res.output.split())
    assert res.exit_code == 1, res.output
    assert str(bad) in text and "disc_temp_spot" in text, text
    assert "°C labelled K?" in text and "set the channel's unit to degC" in text, text
    assert "Traceback" not in res.output


def test_degc_labelled_kelvin_fails_its_batch_session(tmp_path: Path) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    _celsius_labelled_kelvin(folder / "as_kelvin.csv")
    res = runner.invoke(app, ["batch", str(folder), "--out", str(tmp_path / "o"), "--json"])
    assert res.exit_code == 3, res.output
    (session,) = json.loads(res.stdout)["sessions"]
    assert session["status"] == "failed" and "disc_temp_spot1" in session["reason"]
    assert "°C labelled K?" in session["reason"], session


def test_a_race_pyrometer_in_degc_labelled_kelvin_is_refused(tmp_path: Path) -> None:
    # a race's single spot is hot: only its warm-up past the floor reads below -50 degC
    table = pq.read_table(SAMPLE_CSV.with_name("mugello_race_single.parquet"))
    fields = [f.with_metadata({**(f.metadata or {}), b"unit": b"K"})
              if f.name == "disc_temp" else f for f in table.schema]
    bad = tmp_path / "race_as_kelvin.parquet"
    pq.write_table(table.cast(pa.schema(fields, metadata=table.schema.metadata)), bad)
    res = _estimate(bad, tmp_path)
    assert res.exit_code == 1, res.output
    assert "disc_temp" in res.output and "°C labelled K?" in " ".join(res.output.split())


def test_a_loggers_no_reading_code_is_left_out_not_refused() -> None:
    """A constant sentinel far below the air (-999 for 'no reading' while the disc is under
    the floor) is no mislabelled unit: the °C-labelled-K check lets it through."""
    from brakethermo.io.plausibility import check_pyrometer

    t = np.concatenate([np.full(100, -999.0), np.linspace(150.0, 520.0, 400),
                        np.full(50, -999.0), np.linspace(500.0, 200.0, 300)])
    check_pyrometer(t, np.zeros(t.size, bool), 24.0, 0.1)  # no DataError
    varying = t - 273.15  # the same disc in degC labelled K, its cold start read
    varying[:100] = np.linspace(-180.0, -120.0, 100)
    varying[500:550] = np.linspace(-130.0, -150.0, 50)
    with pytest.raises(DataError, match="labelled K"):
        check_pyrometer(varying, np.zeros(t.size, bool), 24.0, 0.1)


@pytest.mark.parametrize("code", [-999.0, -273.15])
def test_a_loggers_no_reading_code_in_a_file_is_left_out(tmp_path: Path, code: float) -> None:
    """Through the reader and the grid (which puts values between the code and the first
    readings): a race whose pyrometer logs a code before the disc passes its floor runs
    (review: refused whole, and -273.15 told to 'set the channel's unit to degC')."""
    table = pq.read_table(SAMPLE_CSV.with_name("mugello_race_single.parquet"))
    temp = table.column("disc_temp").to_numpy(zero_copy_only=False).astype(float)
    time = table.column("time").to_numpy()
    temp[np.isnan(temp) & (time < 31.4)] = code
    i = table.column_names.index("disc_temp")
    bad = tmp_path / "race_code.parquet"
    pq.write_table(table.set_column(i, table.schema.field(i), pa.array(temp)), bad)
    res = _estimate(bad, tmp_path)
    assert res.exit_code == 0, res.output


def _air_in(unit: str, dst: Path) -> Path:
    """The shipped multi-spot CSV with its air channel's unit cell saying ``unit``."""
    lines = SAMPLE_CSV.read_text().splitlines(keepends=True)
    dst.write_text(lines[0].replace("ambient_temp [degC]", f"ambient_temp [{unit}]")
                   + "".join(lines[1:]))
    return dst


def test_an_air_temperature_no_session_runs_in_is_refused(tmp_path: Path) -> None:
    """The air in degC labelled K read -249 degC and a four-spot session was diagnosed
    with a named effect, exit 0 (review); the same values labelled degF (-4 degC air, a
    cold day) are air a session may run in, and pass."""
    res = runner.invoke(app, ["diagnose", str(_air_in("K", tmp_path / "air_K.csv")),
                              "--out", str(tmp_path / "o")])
    assert res.exit_code == 1, res.output
    text = " ".join(res.output.split())
    assert "ambient_temp" in text and "degC labelled K?" in text, text
    assert "Traceback" not in res.output
    res = runner.invoke(app, ["diagnose", str(_air_in("degF", tmp_path / "air_F.csv")),
                              "--out", str(tmp_path / "o2")])
    assert res.exit_code == 0, res.output
