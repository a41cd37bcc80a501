"""Issue 18 items 4-5: mutated disc sessions through the CLI.

Each case writes a one-lap four-spot session with one thing wrong (a unit mislabelled, a
signal scaled, zeroed, negated or stuck, a malformed file) and runs a disc command on
it. A case passes when the command exits 1 with one clear line naming the cause (no
traceback), or exits 0 with finite results; never a traceback, never a runaway.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from _synth_race import UNITS, session_file_frame
from typer.testing import CliRunner

from brakethermo.cli import app

CASE_BUDGET_S = 60.0
FACTS = {"vehicle": "demo bike", "track": "demo ring", "date": "2026-05-01",
         "disc": "cc-340-8", "ambient_temp_c": "25"}


def _write(frame: pd.DataFrame, path: Path, units: dict[str, bytes] | None = None,
           session_meta: bytes | None = None) -> Path:
    """Write ``frame`` as a logger's Parquet export; ``units`` overrides field units."""
    table = pa.Table.from_pandas(frame, preserve_index=False)
    over = units or {}
    fields = []
    for f in table.schema:
        if f.name == "time":
            fields.append(f)
            continue
        unit = over.get(f.name, UNITS.get(f.name, "degC").encode())
        fields.append(f.with_metadata({b"unit": unit}))
    meta = {b"session": session_meta if session_meta is not None
            else json.dumps(FACTS).encode()}
    pq.write_table(pa.Table.from_arrays(table.columns, schema=pa.schema(fields))
                   .replace_schema_metadata(meta), path)
    return path


def _base() -> pd.DataFrame:
    return session_file_frame(1, seed=7, multi=True)


def _scaled(column: str, factor: float) -> Callable[[Path], Path]:
    def build(path: Path) -> Path:
        frame = _base()
        frame[column] = frame[column] * factor
        return _write(frame, path)
    return build


def _spots_plus(offset: float) -> Callable[[Path], Path]:
    def build(path: Path) -> Path:
        frame = _base()
        for i in range(1, 5):
            frame[f"disc_temp_spot{i}"] += offset
        return _write(frame, path)
    return build


def _stuck(path: Path) -> Path:
    frame = _base()
    frame["disc_temp_spot3"] = 300.0
    return _write(frame, path)


def _duplicate_columns(path: Path) -> Path:
    frame = _base()
    table = pa.Table.from_pandas(frame, preserve_index=False)
    table = table.append_column("speed", table.column("speed"))
    pq.write_table(table.replace_schema_metadata({b"session": json.dumps(FACTS).encode()}),
                   path)
    return path


def _bad_unit_bytes(path: Path) -> Path:
    return _write(_base(), path, units={"speed": b"m/s\xff\xfe"})


def _nested_json(path: Path) -> Path:
    return _write(_base(), path, session_meta=b"[" * 100_000 + b"]" * 100_000)


def _long_name(path: Path) -> Path:
    return _write(_base(), path.with_name("s" * 240 + ".parquet"))


# (case id, builder, words the error line must hold; None = must succeed with finite output)
CASES = [
    ("wheel_rpm_as_rad_s", _scaled("wheel_speed_front", 60 / (2 * np.pi)), "rpm labelled rad/s"),
    ("wheel_x1e-3", _scaled("wheel_speed_front", 1e-3), "wheel_speed_front"),
    ("speed_kmh_as_m_s", _scaled("speed", 3.6), "km/h"),
    ("speed_zeroed", _scaled("speed", 0.0), "zeroed"),
    ("speed_negated", _scaled("speed", -1.0), "other sign"),
    ("wheel_zeroed", _scaled("wheel_speed_front", 0.0), "zeroed"),
    ("pressure_zeroed", _scaled("brake_pressure_front", 0.0), "zeroed"),
    ("pressure_negated", _scaled("brake_pressure_front", -1.0), "other sign"),
    ("pressure_x1e-3", _scaled("brake_pressure_front", 1e-3), "never above 1 bar"),
    ("pyrometer_stuck", _stuck, "stuck"),
    ("duplicate_columns", _duplicate_columns, "more than once"),
    ("unit_not_utf8", _bad_unit_bytes, "not UTF-8"),
    ("nested_json_facts", _nested_json, "session"),
    ("long_file_name", _long_name, None),
]


def _run(*args: str):
    t0 = time.perf_counter()
    res = CliRunner().invoke(app, [str(a) for a in args])
    return res, time.perf_counter() - t0


def _assert_clear(res, words: str | None, elapsed: float) -> None:
    assert elapsed < CASE_BUDGET_S, f"runaway: {elapsed:.0f} s"
    assert "Traceback" not in res.output, res.output
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise AssertionError(f"uncaught {type(res.exception).__name__}: {res.exception}")
    if words is None:
        assert res.exit_code == 0, res.output
        return
    assert res.exit_code == 1, res.output
    assert words in res.output, res.output


@pytest.mark.parametrize(("case", "build", "words"), CASES, ids=[c[0] for c in CASES])
def test_inspect_mutation(case, build, words, tmp_path):
    path = build(tmp_path / "s.parquet")
    res, elapsed = _run("inspect", path)
    # inspect lists channels; physics checks belong to the commands that compute.
    reader_case = case in {"duplicate_columns", "unit_not_utf8", "nested_json_facts"}
    _assert_clear(res, words if reader_case else None, elapsed)


# A full estimate takes tens of seconds: the long-name case is checked on the staging
# functions below instead.
ESTIMATE_CASES = [c for c in CASES if c[0] != "long_file_name"]


@pytest.mark.parametrize(("case", "build", "words"), ESTIMATE_CASES,
                         ids=[c[0] for c in ESTIMATE_CASES])
def test_estimate_mutation(case, build, words, tmp_path):
    path = build(tmp_path / "s.parquet")
    out = tmp_path / "out"
    res, elapsed = _run("estimate", path, "--out", out, "--no-reports", "--no-smoother",
                        "--nodes", "12")
    _assert_clear(res, words, elapsed)
    if words is None:
        summaries = list(out.rglob("summary.json"))
        assert summaries, res.output
        text = summaries[0].read_text()
        assert "NaN" not in text and "Infinity" not in text


def test_stuck_span_is_a_warning_and_left_out():
    from brakethermo.io.plausibility import unusable_readings

    temps = np.linspace(20.0, 400.0, 3000)
    temps[1000:2000] = 300.0
    mask, warnings = unusable_readings(temps, 0.1, "TDisc3")
    assert len(warnings) == 1 and "TDisc3: constant at 300.0 °C for 100 s" in warnings[0]
    assert "left out" in warnings[0]
    assert mask[1000:2000].all() and mask.sum() == 1000


def test_a_clipped_pyrometer_is_found_and_its_plateaus_left_out():
    """A pyrometer whose range ends below the disc's peaks reads exactly its top value
    at every hot stop; taken as measurements, the peaks came out 90 degC low."""
    from brakethermo.io.plausibility import unusable_readings

    t = np.arange(0.0, 300.0, 0.1)
    rng = np.random.default_rng(5)
    temps = 400.0 + 200.0 * np.sin(2 * np.pi * t / 60.0) + rng.normal(0, 2, t.size)
    mask, warnings = unusable_readings(temps, 0.1, "TDisc3")
    assert not mask.any() and warnings == []  # a noisy peak is never repeated exactly
    clipped = np.minimum(temps, 550.0)
    mask, warnings = unusable_readings(clipped, 0.1, "TDisc3")
    assert len(warnings) == 1 and "reads exactly 550.0 °C" in warnings[0]
    assert "in 5 spans" in warnings[0]
    assert np.array_equal(mask, clipped >= 550.0)


def test_clean_session_passes_every_check(tmp_path):
    from brakethermo.io.load import load_session
    from brakethermo.pipelines.inputs import disc_inputs
    from brakethermo.thermal.disc import load_disc

    session = load_session(_write(_base(), tmp_path / "s.parquet"))
    inputs = disc_inputs(session, load_disc("cc-340-8"))
    assert not any("constant at" in w for w in inputs.warnings)


def test_long_names_stage_and_replace(tmp_path):
    from brakethermo.io.atomic import atomic_dir, clean_stale_stages, write_text_atomic

    name = "s" * 250
    with atomic_dir(tmp_path / name) as stage:
        (stage / "a.txt").write_text("1")
    with atomic_dir(tmp_path / name) as stage:  # replaces an existing folder
        (stage / "a.txt").write_text("2")
    assert (tmp_path / name / "a.txt").read_text() == "2"
    write_text_atomic(tmp_path / (name[:240] + ".json"), "{}")
    assert (tmp_path / (name[:240] + ".json")).read_text() == "{}"
    assert clean_stale_stages(tmp_path / name) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, name[:240] + ".json"])


def test_result_checks_flag_impossible_estimates():
    from brakethermo.pipelines.checks import check_estimate_result

    clean = np.linspace(25.0, 700.0, 500)
    assert check_estimate_result(clean, np.full(500, 1.1)) == []
    hot = check_estimate_result(np.append(clean, 4017.0), np.full(500, 1.1))
    assert len(hot) == 1 and "4017 °C" in hot[0]
    nis = check_estimate_result(clean, np.full(500, 35.0))
    assert len(nis) == 1 and "mean NIS 35.0" in nis[0]
    nan = check_estimate_result(np.append(clean, np.nan), np.full(500, 1.0))
    assert len(nan) == 1 and "1 estimated temperatures are not finite" in nan[0]


@pytest.mark.parametrize(("second_unit", "words"),
                         [("m/s", "registered twice with different units"), ("km/h", None)])
def test_mcap_topic_registered_twice(tmp_path, second_unit, words):
    from mcap.writer import Writer

    path = tmp_path / "twice.mcap"
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start()
        sid = w.register_schema("v", "jsonschema", b"{}")
        first = w.register_channel("speed", "json", sid, {"unit": "km/h"})
        second = w.register_channel("speed", "json", sid, {"unit": second_unit})
        for k in range(200):
            w.add_message(first if k % 2 else second, k * 10_000_000, b'{"value": 100.0}', 0)
        w.finish()
    res, elapsed = _run("inspect", path)
    _assert_clear(res, words, elapsed)


def test_mdf_channel_in_two_groups_is_said(tmp_path):
    from asammdf import MDF, Signal

    from brakethermo.io.load import load_session

    t_old, t_new = np.arange(300) * 0.1, np.arange(600) * 0.05
    mdf = MDF(version="4.10")
    mdf.append([Signal(np.full(300, 400.0), t_old, name="disc_temp", unit="degC"),
                Signal(np.full(300, 30.0), t_old, name="speed", unit="m/s")])
    mdf.append([Signal(np.full(600, 500.0), t_new, name="disc_temp", unit="degC")])
    path = tmp_path / "two.mf4"
    mdf.save(path)
    mdf.close()
    session = load_session(path)
    assert session.values("disc_temp")[5] == pytest.approx(500.0)
    said = [w for w in session.warnings if "channel 'disc_temp' is in groups 0, 1" in w]
    assert len(said) == 1 and "using group 1 (600 samples, the most)" in said[0]
    assert "disc_temp [group 0]" in said[0] and "+100" in said[0]
    # a copy in another unit: its units said, not a difference of numbers in two units
    mdf = MDF(version="4.10")
    mdf.append([Signal(np.full(300, 673.15), t_old, name="disc_temp", unit="K"),
                Signal(np.full(300, 30.0), t_old, name="speed", unit="m/s")])
    mdf.append([Signal(np.full(600, 400.0), t_new, name="disc_temp", unit="degC")])
    mdf.save(tmp_path / "kelvin.mf4")
    mdf.close()
    said = [w for w in load_session(tmp_path / "kelvin.mf4").warnings if "groups 0, 1" in w]
    assert len(said) == 1 and "in K, not degC" in said[0] and "-273" not in said[0]


@pytest.mark.parametrize(("table", "words"), [
    ("[effects.sensor_lag]\n", "'effects.sensor_lag.tau_s': expected a finite number between "
                               "0.01 and 3, found nothing (the key is missing)"),
    ("[effects.sensor_lag]\ntau_s = 9.0\n", "found 9.0"),
    ("[effects.sensor_lag]\ntau_s = nan\n", "effects.sensor_lag.tau_s"),
    ("[effects.friction_temperature]\nbeta = 0.1\n", "effects.friction_temperature.t_mid"),
])
def test_effect_table_missing_or_out_of_bounds(tmp_path, table, words):
    from brakethermo.config import config_dir

    law = tmp_path / "h_law.toml"
    law.write_text((config_dir() / "hlaw" / "cc-340-8.toml").read_text() + "\n" + table)
    path = _write(_base(), tmp_path / "s.parquet")
    res, elapsed = _run("estimate", path, "--h-law", law, "--out", tmp_path / "o",
                        "--no-reports")
    _assert_clear(res, words, elapsed)
    assert "h_law.toml" in res.output


def _beacons(path: Path, times: list[float], values: list[float]) -> Path:
    frame = session_file_frame(4, seed=7, multi=True)
    frame["lap_beacon"] = np.nan
    for t, v in zip(times, values, strict=True):
        frame.loc[round(t * 10), "lap_beacon"] = v
    return _write(frame, path)


def test_beacon_counting_down_is_renumbered_and_said(tmp_path):
    from brakethermo.io.load import load_session

    session = load_session(_beacons(tmp_path / "s.parquet", [96.0, 192.0, 288.0],
                                    [3.0, 2.0, 1.0]))
    assert [lap.lap for lap in session.laps] == [0, 1, 2, 3]
    assert session.laps[0].start_s == 0.0 and session.laps[1].start_s == pytest.approx(96.0)
    assert any("3, 2, 1 count down" in w for w in session.warnings)


def test_laps_of_implausible_length_are_said(tmp_path):
    from brakethermo.io.load import load_session

    # a misplaced beacon: flying laps of 40 s and 152 s on a 96 s track
    session = load_session(_beacons(tmp_path / "s.parquet", [96.0, 136.0, 288.0],
                                    [1.0, 2.0, 3.0]))
    said = [w for w in session.warnings if "implausibly different length" in w]
    assert len(said) == 1 and "lap 1: 40.0 s, lap 2: 152.0 s" in said[0]
    clean = load_session(_beacons(tmp_path / "c.parquet", [96.0, 192.0, 288.0],
                                  [1.0, 2.0, 3.0]))
    assert not any("implausibly" in w for w in clean.warnings)


@pytest.mark.parametrize("value", ["nan", "inf", "0"])
def test_gap_limit_must_be_finite_and_positive(tmp_path, value):
    path = _write(_base(), tmp_path / "s.parquet")
    res, elapsed = _run("inspect", path, "--gap-limit", value)
    _assert_clear(res, "gap limit must be a finite number of seconds > 0", elapsed)


def test_same_session_twice_days_apart_is_refused(tmp_path):
    frame = _base()
    later = frame.copy()
    later["time"] = later["time"] + 5 * 86400.0
    path = _write(pd.concat([frame, later], ignore_index=True), tmp_path / "s.parquet")
    res, elapsed = _run("inspect", path)
    _assert_clear(res, "the log has a pause of 5.00 days", elapsed)


def test_short_fast_burst_does_not_set_the_grid(tmp_path):
    from brakethermo.io.load import load_session

    frame = _base()
    burst_t = 10.0 + np.arange(10_000) * 1e-5  # 0.1 s at 100 kHz
    burst = pd.DataFrame({"time": burst_t, "ambient_temp": np.full(burst_t.size, 25.0)})
    both = pd.concat([frame, burst], ignore_index=True).sort_values("time")
    t0 = time.perf_counter()
    session = load_session(_write(both.reset_index(drop=True), tmp_path / "s.parquet"),
                           rate_hz=None)  # the fastest rate, as the rig commands ask
    assert time.perf_counter() - t0 < 20.0
    assert len(session.frame) < 20 * len(frame)


def test_pyrometer_in_kelvin_labelled_degc_is_said(tmp_path):
    """Refused when the disc rests steady at air + 273 before the first stop; otherwise (a
    session may start on a hot disc) a loud warning naming the kelvin possibility."""
    path = _spots_plus(273.15)(tmp_path / "k.parquet")
    res, elapsed = _run("estimate", path, "--out", tmp_path / "o", "--no-smoother",
                        "--no-reports", "--json")
    assert elapsed < CASE_BUDGET_S and "Traceback" not in res.output
    if res.exit_code == 1:
        assert "kelvin labelled degC" in res.output
    else:
        assert res.exit_code == 0, res.output
        assert any("kelvin labelled degC" in w
                   for w in json.loads(res.stdout)["run"]["warnings"]), res.stdout


def test_brake_pressure_in_mpa_labelled_bar_is_said(tmp_path):
    """Brake pressure a tenth of the truth (MPa read as bar) passes the input checks; the
    filter then scales the braking power about tenfold to follow the pyrometer, which no
    pad's friction does: a loud warning (the estimate was silent, exit 0)."""
    from brakethermo.pipelines.checks import check_power_scale

    path = _scaled("brake_pressure_front", 0.1)(tmp_path / "mpa.parquet")
    res, elapsed = _run("estimate", path, "--out", tmp_path / "o", "--no-smoother",
                        "--no-reports", "--json", "--nodes", "12")
    assert elapsed < CASE_BUDGET_S and res.exit_code == 0, res.output
    said = [w for w in json.loads(res.stdout)["run"]["warnings"] if "had to be scaled" in w]
    assert len(said) == 1 and "brake_pressure_front" in said[0], res.stdout
    braking = np.ones(100, dtype=bool)
    assert check_power_scale(np.full(100, 1.4), braking) == []  # pads do vary
    assert check_power_scale(np.full(100, 0.2), braking)  # kPa read as bar


def test_diagnose_says_a_misplaced_beacon_on_the_console(tmp_path):
    """diagnose builds its lap split on the beacon: the session's lap warnings are
    printed with its own (they were only in diagnosis.json's run.input_warnings)."""
    path = _beacons(tmp_path / "s.parquet", [96.0, 136.0, 288.0], [1.0, 2.0, 3.0])
    res, elapsed = _run("diagnose", path, "--out", tmp_path / "o", "--effects", "sensor_lag")
    assert elapsed < CASE_BUDGET_S and res.exit_code == 0, res.output
    assert "implausibly different length" in res.output


def test_a_first_reading_far_above_the_floor_after_a_silent_start_is_said():
    """A race's pyrometer is silent while the disc is below its floor and first reads it
    near the floor; the same readings in kelvin labelled degC first read ~380 °C (the
    estimate was silent: peaks of 1000 °C, exit 0)."""
    from brakethermo.io.plausibility import check_pyrometer

    t = np.arange(3000) * 0.1
    temps = np.where(t < 31.4, np.nan, 106.0 + 2.0 * (t - 31.4))
    braking = (t % 100.0) < 5.0
    assert not any("silent" in w for w in check_pyrometer(temps, braking, 25.0, 0.1))
    said = [w for w in check_pyrometer(temps + 273.15, braking, 25.0, 0.1)
            if "silent for the first 31 s" in w]
    assert len(said) == 1 and "kelvin labelled degC" in said[0]
