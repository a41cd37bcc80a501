"""Simulated sessions: plausibility, effect signatures, determinism, writers round trip."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from brakethermo.errors import ConfigError
from brakethermo.io.writers import Channel, SessionData, mcap_bytes, write_session
from brakethermo.sim.effects import EFFECT_NAMES, make_effects
from brakethermo.sim.sensors import first_order_lag
from brakethermo.sim.session import SimConfig, SimResult, simulate, write_simulation
from brakethermo.sim.track import load_track

SPOTS = ["spot1", "spot2", "spot3", "spot4"]


def _truth(r: SimResult) -> pd.DataFrame:
    return r.truth.to_pandas()


def _channel(r: SimResult, name: str) -> Channel:
    return next(c for c in r.session.channels if c.name == name)


@pytest.fixture(scope="module")
def fast() -> SimResult:
    return simulate(SimConfig(track="mugello-like", laps=3, seed=5))


@pytest.fixture(scope="module")
def runs() -> dict[str, SimResult]:
    """Baseline (all mild) and each effect strong, same seed and track."""
    cfg = dict(track="mugello-like", laps=2, seed=3)
    out = {"base": simulate(SimConfig(**cfg))}
    for name in EFFECT_NAMES:
        out[name] = simulate(SimConfig(**cfg, effects=(name,)))
    return out


# --- plausibility -------------------------------------------------------------------


def test_fast_track_plausibility_bands(fast):
    truth = _truth(fast)
    warm = truth[truth.lap >= 2]
    assert 650.0 <= warm[SPOTS].to_numpy().max() <= 950.0
    braking = warm[warm.q_brake > 0]
    # Spots on the rubbed band differ by tens of degC; spot 1 (inside the pad band, not
    # rubbed) lags them, typically by ~200 degC in braking.
    contact = braking[SPOTS[1:]].max(axis=1) - braking[SPOTS[1:]].min(axis=1)
    assert 15.0 <= contact.max() <= 200.0
    spread = braking[SPOTS].max(axis=1) - braking[SPOTS].min(axis=1)
    assert 100.0 <= spread.median() <= 250.0
    # Cooling on the longest straight down to a few hundred degC.
    a, b = load_track("mugello-like").longest_straight()
    dist = np.interp(warm.time, _channel(fast, "distance").time, _channel(fast, "distance").value)
    straight = warm[(dist > a + 100) & (dist < b)]
    assert 200.0 <= straight.contact_avg.min() <= 500.0
    assert 330.0 <= truth.speed.max() <= 360.0
    assert 50.0 <= truth.h.min() and truth.h.max() <= 250.0
    # Pressure stays in the range of a race front brake.
    p = _channel(fast, "brake_pressure_front").value
    assert 6.0 <= p.max() <= 20.0


def test_session_channels_and_facts(fast):
    names = [c.name for c in fast.session.channels]
    for n in (
        "speed",
        "wheel_speed_front",
        "brake_pressure_front",
        "ambient_temp",
        "distance",
        "lap_beacon",
        *[f"disc_temp_spot{i}" for i in range(1, 5)],
    ):
        assert n in names
    facts = fast.session.facts
    assert {"vehicle", "track", "date", "disc", "ambient_temp_c", "seed", "effects"} <= set(facts)
    assert facts["disc"] == "cc-340-8"
    beacon = _channel(fast, "lap_beacon")
    assert beacon.value.tolist() == [0.0, 1.0, 2.0, 3.0] and beacon.time[0] == 0.0
    ir = _channel(fast, "disc_temp_spot3").value
    assert np.nanmin(ir) >= 100.0 and np.isnan(ir[:10]).all()  # cold at pit exit: floor
    for c in fast.session.channels:
        assert np.all(np.diff(c.time) > 0) and c.time[0] >= 0.0


def test_single_sensor_writes_only_disc_temp():
    r = simulate(SimConfig(track="tight-like", laps=1, seed=8, sensor="single"))
    names = [c.name for c in r.session.channels]
    assert "disc_temp" in names and not any(n.startswith("disc_temp_spot") for n in names)
    # At the spot-3 radius: it tracks the truth's spot 3 best.
    ir = _channel(r, "disc_temp")
    truth = _truth(r)
    rmse = {
        s: np.sqrt(np.nanmean((ir.value - np.interp(ir.time, truth.time, truth[s])) ** 2))
        for s in SPOTS
    }
    assert min(rmse, key=rmse.get) == "spot3"


# --- effects --------------------------------------------------------------------------


def _ir_vs_truth(r: SimResult, spot: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ch = _channel(r, f"disc_temp_spot{spot}")
    truth = _truth(r)
    t_true = np.interp(ch.time, truth.time, truth[f"spot{spot}"])
    rate = np.interp(ch.time, truth.time, np.gradient(truth[f"spot{spot}"], truth.time))
    ok = np.isfinite(ch.value)
    return ch.value[ok], t_true[ok], rate[ok]


def _fitted_lag(r: SimResult) -> float:
    """The first-order time constant that best maps the truth onto the IR reading."""
    ch = _channel(r, "disc_temp_spot3")
    truth = _truth(r)
    ok = np.isfinite(ch.value)
    true = truth.spot3.to_numpy(np.float64)
    taus = np.arange(0.0, 0.8, 0.01)
    rmse = [
        np.sqrt(
            np.mean(
                (ch.value[ok] - np.interp(ch.time[ok], truth.time, first_order_lag(true, 0.1, tau)))
                ** 2
            )
        )
        for tau in taus
    ]
    return float(taus[int(np.argmin(rmse))])


def _same_truth(a: SimResult, b: SimResult, cols=(*SPOTS, "q_brake", "h")) -> bool:
    ta, tb = _truth(a), _truth(b)
    return all(np.array_equal(ta[c].to_numpy(), tb[c].to_numpy()) for c in cols)


def _same_channel(a: SimResult, b: SimResult, name: str) -> bool:
    return np.array_equal(_channel(a, name).value, _channel(b, name).value)


def test_effect_names_and_levels():
    assert make_effects().levels() == {n: "mild" for n in EFFECT_NAMES}
    assert make_effects(["sensor_lag"]).levels()["sensor_lag"] == "strong"
    with pytest.raises(ConfigError, match="unknown effect"):
        make_effects(["sensor-lag"])


def test_sensor_lag_delays_ir_only(runs):
    base, lag = runs["base"], runs["sensor_lag"]
    assert _same_truth(base, lag)
    assert _same_channel(base, lag, "brake_pressure_front")
    assert _fitted_lag(base) < 0.12
    assert 0.28 < _fitted_lag(lag) < 0.42


def test_emissivity_error_reads_low_when_hot_only_in_ir(runs):
    base, emi = runs["base"], runs["emissivity_error"]
    assert _same_truth(base, emi)
    assert _same_channel(base, emi, "speed")
    mb, tb, _ = _ir_vs_truth(base)
    me, te, _ = _ir_vs_truth(emi)
    hot_b, hot_e = tb > 550, te > 550
    warm_b, warm_e = (tb > 120) & (tb < 250), (te > 120) & (te < 250)
    err_hot = np.mean(me[hot_e] - te[hot_e])
    assert abs(np.mean(mb[hot_b] - tb[hot_b])) < 6.0
    assert err_hot < -0.04 * np.mean(te[hot_e])  # several percent low when hot
    assert np.mean(me[warm_e] - te[warm_e]) > err_hot + 8.0  # less when cooler
    assert np.mean(mb[warm_b] - tb[warm_b]) > -5.0


def test_h_speed_knee_only_above_knee_speed(runs):
    base, knee = _truth(runs["base"]), _truth(runs["h_speed_knee"])
    slow = base.speed < 0.8 * 350.0
    fast_ = base.speed > 320.0
    assert np.allclose(base.h[slow], knee.h[slow], rtol=1e-6)
    ratio = knee.h[fast_] / base.h[fast_]
    assert ratio.min() > 1.1
    assert knee.spot3.max() < base.spot3.max()  # extra cooling at top speed


def test_slipstream_reduces_h_on_flagged_straights_only(runs):
    base, slip = _truth(runs["base"]), _truth(runs["slipstream"])
    flag = slip.slipstream.to_numpy()
    assert flag.any() and not base.slipstream.any()
    ratio = (slip.h / base.h).to_numpy()
    assert np.all((ratio[flag] > 0.64) & (ratio[flag] < 0.76))
    assert np.allclose(ratio[~flag], 1.0, rtol=1e-6)
    assert (slip.speed[flag] > 150).all()
    assert (slip.q_brake[flag] == 0).all()


def test_friction_temperature_changes_pressure_not_heat(runs):
    base, fric = runs["base"], runs["friction_temperature"]
    assert _same_truth(base, fric)
    assert not _same_channel(base, fric, "brake_pressure_front")
    tf = _truth(fric)
    braking = tf.q_brake > 1000
    ratio = (tf.q_brake_nominal / tf.q_brake)[braking]
    assert np.allclose(ratio, 1.0 / tf.mu_ratio[braking], rtol=1e-4)
    assert tf.mu_ratio.max() - tf.mu_ratio.min() > 0.15  # +-15-20 % over the session
    tb = _truth(base)
    assert tb.mu_ratio.max() - tb.mu_ratio.min() < 0.06


def test_thickness_gradient_surface_far_hotter_than_mid(runs):
    base, thick = _truth(runs["base"]), _truth(runs["thickness_gradient"])
    gap_b = (base.spot3 - base.spot3_mid).max()
    gap_t = (thick.spot3 - thick.spot3_mid).max()
    assert 10.0 < gap_b < 100.0  # tens of degC with the mild k_z
    assert gap_t > 3.0 * gap_b and gap_t > 200.0
    assert np.array_equal(base.q_brake, thick.q_brake)


def test_power_distribution_strongly_non_uniform_and_corner_dependent(runs):
    base, pd_ = _truth(runs["base"]), _truth(runs["power_distribution"])
    w = ["w1", "w2", "w3"]
    assert (base[w].dropna() - 1 / 3).abs().to_numpy().max() < 0.1
    wd = pd_[w].dropna()
    assert (wd - 1 / 3).abs().to_numpy().max() > 0.2
    braking = pd_.q_brake > 0
    spread = lambda t: (t[SPOTS[1:]].max(axis=1) - t[SPOTS[1:]].min(axis=1))[braking].mean()  # noqa: E731
    assert spread(pd_) > 1.5 * spread(base)
    assert np.array_equal(base.h, pd_.h)


# --- determinism and writers -----------------------------------------------------------


@pytest.mark.parametrize("ext", ["mcap", "parquet", "csv"])
def test_same_seed_same_bytes(tmp_path: Path, ext: str):
    cfg = SimConfig(track="tight-like", laps=1, seed=21, effects=("slipstream",))
    paths = []
    for k in range(2):
        s, t = write_simulation(simulate(cfg), tmp_path / f"run{k}" / f"s.{ext}")
        paths.append((s, t))
    assert paths[0][0].read_bytes() == paths[1][0].read_bytes()
    assert paths[0][1].read_bytes() == paths[1][1].read_bytes()
    other, _ = write_simulation(
        simulate(SimConfig(track="tight-like", laps=1, seed=22)), tmp_path / f"other.{ext}"
    )
    assert other.read_bytes() != paths[0][0].read_bytes()


@pytest.fixture(scope="module")
def short() -> SimResult:
    return simulate(SimConfig(track="tight-like", laps=1, seed=9))


def test_mcap_round_trip(tmp_path: Path, short: SimResult):
    path, truth_path = write_simulation(short, tmp_path / "s.mcap")
    with path.open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        topics = {c.topic: c for c in summary.channels.values()}
        schemas = summary.schemas
        got: dict[str, list[tuple[int, float]]] = {}
        for schema, channel, message in reader.iter_messages():
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            got.setdefault(channel.topic, []).append(
                (message.log_time, json.loads(message.data)["value"])
            )
    with path.open("rb") as fh:
        meta = {m.name: m.metadata for m in make_reader(fh).iter_metadata()}
    assert meta["session"]["disc"] == "cc-340-8"
    assert all(s.encoding == "jsonschema" for s in schemas.values())
    for ch in short.session.channels:
        assert topics[ch.name].metadata.get("unit", "") == ch.unit
        ok = np.isfinite(ch.value)
        t, v = np.array(got[ch.name]).T
        assert np.array_equal(t.astype(np.int64), np.round(ch.time[ok] * 1e9).astype(np.int64))
        assert np.allclose(v, ch.value[ok], atol=10.0**-ch.decimals)
    truth = pq.read_table(truth_path)
    assert "brakethermo_truth" in json.loads(
        json.dumps({k.decode(): 1 for k in truth.schema.metadata})
    )
    assert np.allclose(np.diff(truth.column("time").to_numpy()), 0.1)


def test_mcap_grouped_topic(tmp_path: Path, short: SimResult):
    path, _ = write_simulation(short, tmp_path / "g.mcap", grouped=True)
    with path.open("rb") as fh:
        reader = make_reader(fh)
        msgs = [
            (c.topic, json.loads(m.data))
            for _, c, m in reader.iter_messages()
            if c.topic == "disc_temp"
        ]
        units = {c.topic: c.metadata.get("unit") for c in reader.get_summary().channels.values()}
    assert units["disc_temp"] == "degC"
    assert msgs and set().union(*(set(d) for _, d in msgs)) == {"spot1", "spot2", "spot3", "spot4"}
    load = pytest.importorskip("brakethermo.io.load")
    frame = load.load_session(path).frame
    assert {f"disc_temp_spot{i}" for i in range(1, 5)} <= set(frame.columns)


def test_track_validation(tmp_path: Path):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        "pit_speed_kmh = 60.0\npit_lane_m = 100.0\nambient_c = 20.0\n"
        'segments = [{ kind = "straight", length_m = 500.0 },'
        ' { kind = "hairpin", length_m = 50.0, apex_kmh = 60.0 }]\n'
    )
    with pytest.raises(
        ConfigError, match=r"key 'segments\[2\]\.kind': expected one of 'straight', 'corner'"
    ):
        load_track(bad)
    with pytest.raises(ConfigError, match="unknown track"):
        load_track("no-such-track")
    fast_track = load_track("mugello-like")
    assert 5000.0 < fast_track.length < 5500.0 and len(fast_track.corners) >= 10


def test_parquet_and_csv_round_trip(tmp_path: Path, short: SimResult):
    pq_path, _ = write_simulation(short, tmp_path / "s.parquet")
    table = pq.read_table(pq_path)
    assert json.loads(table.schema.metadata[b"session"])["track"] == "tight-like"
    for ch in short.session.channels:
        field = table.schema.field(ch.name)
        assert (field.metadata or {}).get(b"unit", b"").decode() == ch.unit
        col = table.column(ch.name).to_numpy(zero_copy_only=False)
        t = table.column("time").to_numpy()
        ok = np.isfinite(ch.value)
        rows = np.searchsorted(t, ch.time[ok])
        assert np.allclose(col[rows], ch.value[ok])
        assert np.isfinite(col).sum() == ok.sum()

    csv_path, _ = write_simulation(short, tmp_path / "s.csv")
    df = pd.read_csv(csv_path)
    assert df.columns[0] == "time"
    assert "speed [km/h]" in df.columns and "lap_beacon" in df.columns
    assert df["lap_beacon"].dropna().tolist() == [0.0, 1.0]


def test_load_session_reads_every_format(tmp_path: Path, short: SimResult):
    load = pytest.importorskip("brakethermo.io.load")
    truth = _truth(short)
    for ext in ("mcap", "parquet", "csv"):
        path, _ = write_simulation(short, tmp_path / f"s.{ext}")
        session = load.load_session(path)
        frame = session.frame
        assert {"speed", "brake_pressure_front", "disc_temp_spot3"} <= set(frame.columns)
        n = min(len(frame), len(truth))
        assert np.allclose(frame.time[:n], truth.time[:n])
        assert np.array_equal(frame.lap.to_numpy()[:n], truth.lap.to_numpy()[:n])
        sp = frame.speed.to_numpy()[:n] * 3.6
        assert np.nanmax(np.abs(sp - truth.speed.to_numpy()[:n])) < 5.0


@settings(max_examples=25, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(1, 40), st.floats(1.0, 200.0), st.booleans()),
        min_size=1,
        max_size=4,
    )
)
def test_writers_round_trip_any_channels(spec):
    channels = []
    for i, (n, rate, gaps) in enumerate(spec):
        t = np.round(np.arange(n) / rate + 0.0137 * i, 4)
        v = np.round(np.sin(t * (i + 1)) * 100, 3)
        if gaps:
            v[::3] = np.nan
        channels.append(Channel(f"ch{i}", "bar", t, v, 3))
    data = SessionData(tuple(channels), {"track": "x"})
    buf = io.BytesIO(mcap_bytes(data))
    got: dict[str, list[float]] = {}
    for _, c, m in make_reader(buf).iter_messages():
        got.setdefault(c.topic, []).append(json.loads(m.data)["value"])
    for ch in channels:
        ok = np.isfinite(ch.value)
        assert np.allclose(got.get(ch.name, []), ch.value[ok])


def test_write_session_rejects_unknown_format(tmp_path: Path, short: SimResult):
    with pytest.raises(ConfigError, match="extension"):
        write_session(tmp_path / "s.txt", short.session)


def test_simulate_command_writes_session_and_truth(tmp_path: Path):
    from typer.testing import CliRunner

    from brakethermo.cli import app

    out = tmp_path / "run.parquet"
    res = CliRunner().invoke(
        app,
        [
            "simulate",
            "--track",
            "tight-like",
            "--laps",
            "1",
            "--seed",
            "2",
            "--sensor",
            "single",
            "--effects",
            "sensor_lag,emissivity_error",
            "--out",
            str(out),
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["effects"] == ["sensor_lag", "emissivity_error"]
    assert out.is_file() and (tmp_path / "run.truth.parquet").is_file()
    meta = json.loads(pq.read_schema(tmp_path / "run.truth.parquet").metadata[b"brakethermo_truth"])
    assert meta["effect_levels"]["sensor_lag"] == "strong"
    assert meta["effect_levels"]["slipstream"] == "mild"
    bad = CliRunner().invoke(app, ["simulate", "--effects", "nope", "--out", str(out)])
    assert bad.exit_code == 1 and "unknown effect" in bad.output
