"""load_session end to end: spikes, gaps, grouped-field units, time base, Session.require."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.errors import DataError
from brakethermo.io import load_session


def write_csv(path: Path, t: np.ndarray, columns: dict[str, np.ndarray]) -> Path:
    lines = [",".join(["time [s]", *columns])]
    for i in range(t.size):
        cells = ["" if np.isnan(c[i]) else repr(float(c[i])) for c in columns.values()]
        lines.append(",".join([repr(float(t[i])), *cells]))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_spikes_rejected_and_counted(tmp_path: Path) -> None:
    rng = np.random.default_rng(11)
    t = np.arange(0, 30.0, 0.02)
    clean = 450.0 + 100.0 * np.sin(2 * np.pi * 0.1 * t) + rng.normal(0, 1.0, t.size)
    spiky = clean.copy()
    spiky[[200, 700, 1100]] += [300.0, -250.0, 500.0]
    path = write_csv(tmp_path / "s.csv", t, {"TDiscFL_3 [degC]": spiky, "vFront": 0 * t + 100})
    session = load_session(path)
    assert session.channels["disc_temp_spot3"].spikes == 3
    assert session.channels["speed"].spikes == 0  # only IR channels are filtered
    grid_clean = np.interp(session.time, t, clean)
    assert np.abs(session.values("disc_temp_spot3") - grid_clean).max() < 3.0


def test_gap_limit_option(tmp_path: Path) -> None:
    t = np.arange(0, 20.0, 0.01)
    v = 100.0 + t
    v[(t > 8.0) & (t < 11.0)] = np.nan
    path = write_csv(tmp_path / "g.csv", t, {"vFront [km/h]": v})
    runner = CliRunner()
    out = json.loads(runner.invoke(app, ["inspect", str(path), "--json"]).output)
    (start, duration), = out["channels"][0]["gaps"]
    assert start == pytest.approx(8.0) and duration == pytest.approx(3.0)
    assert any("gap" in w for w in out["warnings"])
    wide = runner.invoke(app, ["inspect", str(path), "--json", "--gap-limit", "5"])
    out = json.loads(wide.output)
    assert out["channels"][0]["gaps"] == []


def test_grouped_field_units_and_time_base(tmp_path: Path) -> None:
    path = tmp_path / "g.mcap"
    base = 1_700_000_000_000_000_000
    with path.open("wb") as fh:
        writer = Writer(fh)
        writer.start()
        group = writer.register_channel("disc_temp", "json", 0,
                                        {"unit": "degC", "unit.spot4": "K"})
        late = writer.register_channel("/vFront", "json", 0, {"unit": "m/s"})
        for i in range(100):
            ns = base + 500_000_000 + i * 20_000_000  # IR starts 0.5 s in ...
            doc = {"spot3": 500.0, "spot4": 773.15}
            writer.add_message(group, ns, json.dumps(doc).encode(), ns)
        for i in range(50):
            ns = base + i * 40_000_000  # ... speed is the earliest channel
            writer.add_message(late, ns, b'{"value": 10.0}', ns)
        writer.finish()
    session = load_session(path)
    assert session.start_epoch_s == pytest.approx(base * 1e-9)
    assert session.time[0] == 0.0
    assert session.channels["disc_temp_spot4"].unit == "K"
    temp = session.values("disc_temp_spot4")
    np.testing.assert_allclose(temp[5:25], 500.0)
    np.testing.assert_allclose(session.values("disc_temp_spot3")[5:25], 500.0)
    np.testing.assert_allclose(session.values("speed")[:20], 10.0)


def test_require_names_channel_aliases_and_file(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "r.csv", np.arange(0, 2.0, 0.1), {"rpmX": np.ones(20)})
    session = load_session(path)
    session.require()
    with pytest.raises(DataError) as err:
        session.require("wheel_speed_front")
    text = str(err.value)
    assert text.startswith(f"{path}: channel 'wheel_speed_front'")
    assert "nWheelF" in text and "the file has: rpmX" in text


def test_gap_limit_must_be_positive(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "p.csv", np.arange(0, 2.0, 0.1), {"vFront": np.ones(20)})
    with pytest.raises(DataError, match="finite number of seconds > 0"):
        load_session(path, gap_limit_s=0.0)


def test_rig_rate_grid_and_single_sample_constant(tmp_path: Path) -> None:
    # A 200 Hz rig log: the grid follows the requested rate, a ramp survives exactly,
    # and a reference logged once (in mm) is a value, not a gap.
    t = np.arange(0, 5.0, 0.005)
    ref = np.full(t.size, np.nan)
    ref[0] = 348.2
    path = write_csv(tmp_path / "rig.csv", t, {
        "wheel_omega [rad/s]": 10.0 + 2.0 * t,
        "rolling_radius_ref [mm]": ref,
    })
    session = load_session(path, rate_hz=200.0, channels=("wheel_omega", "rolling_radius_ref"))
    assert session.dt == pytest.approx(0.005)
    assert session.rate_hz == pytest.approx(200.0)
    np.testing.assert_allclose(session.values("wheel_omega"), 10.0 + 2.0 * session.time,
                               atol=1e-9)
    assert session.constants["rolling_radius_ref"] == pytest.approx(0.3482)
    assert session.constant("rolling_radius_ref") == pytest.approx(0.3482)
    assert "rolling_radius_ref" not in session.channels
    with pytest.raises(DataError, match="single sample"):
        session.require("rolling_radius_ref")
    native = load_session(path, rate_hz=None, channels=("wheel_omega",))
    assert native.rate_hz == pytest.approx(200.0, rel=1e-6)
    assert list(native.channels) == ["wheel_omega"]
    with pytest.raises(DataError, match="grid rate"):
        load_session(path, rate_hz=0.0)
