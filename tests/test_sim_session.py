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
from brakethermo.sim.brake_chain import draw_brake_chain
from brakethermo.sim.effects import (
    EFFECT_NAMES,
    make_effects,
    parse_effects,
    random_strengths,
    strengths_of,
)
from brakethermo.sim.heat import MuLaw
from brakethermo.sim.sensors import first_order_lag
from brakethermo.sim.session import SimConfig, SimResult, simulate, write_simulation
from brakethermo.sim.track import load_track
from brakethermo.thermal.disc import load_disc

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
    assert 620.0 <= warm[SPOTS].to_numpy().max() <= 780.0
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
    lap_times = np.diff(_meta(fast)["beacon_times_s"])[1:]
    assert np.all((lap_times > 105.0) & (lap_times < 125.0))
    assert np.ptp(lap_times) < 1.5


@pytest.mark.parametrize("track", ["mugello-like", "tight-like"])
def test_strong_effects_stay_plausible(track):
    """Every effect at strength 1.3 at once: laps, speeds and temperatures of a race."""
    r = simulate(
        SimConfig(track=track, laps=1, seed=17, effects={n: 1.3 for n in EFFECT_NAMES})
    )
    t = _truth(r)
    warm = t[t.lap >= 1]
    # A thin-skin disc (k_z a third of the datasheet's) runs a far hotter face.
    assert 600.0 <= warm[SPOTS].to_numpy().max() <= 1150.0
    assert warm[SPOTS].to_numpy().min() > 100.0
    assert 280.0 <= t.speed.max() <= 365.0 and t.speed.min() > 50.0
    assert 0.6 < t.mu_ratio.min() and t.mu_ratio.max() < 1.3
    p = _channel(r, "brake_pressure_front").value
    assert 6.0 <= p.max() <= 20.0
    lap_times = np.diff(_meta(r)["beacon_times_s"])
    assert np.all((lap_times > 95.0) & (lap_times < 160.0))
    e = _meta(r)["energy_J"]
    assert abs(e["residual"]) / e["heat_in"] < 0.01


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


def _meta(r: SimResult) -> dict:
    return json.loads(r.truth.schema.metadata[b"brakethermo_truth"])


def _h_without_knee_or_slip(r: SimResult) -> np.ndarray:
    """The true h(V) law without the knee and slipstream, from the truth metadata."""
    law = _meta(r)["h_law"]
    v = _truth(r).speed.to_numpy(np.float64) / 3.6
    return law["h0"] + law["a"] * v ** law["n"]


def _knee_factor(r: SimResult) -> np.ndarray:
    law = _meta(r)["h_law"]
    v = _truth(r).speed.to_numpy(np.float64) / 3.6
    v_k = law["knee_frac"] * law["v_ref_m_s"]
    x = np.maximum(v - v_k, 0.0) / (law["v_ref_m_s"] - v_k)
    return 1.0 + law["knee_gain"] * x ** law["knee_exponent"]


# --- effect strengths: the API -----------------------------------------------------------


def test_effect_strength_parsing_and_validation():
    assert strengths_of(()) == {n: 0.0 for n in EFFECT_NAMES}
    got = parse_effects(" sensor_lag=0.35, friction_temperature ,slipstream=1.5")
    assert got["sensor_lag"] == 0.35 and got["friction_temperature"] == 1.0
    assert got["slipstream"] == 1.5 and got["power_distribution"] == 0.0
    assert list(got) == list(EFFECT_NAMES)
    assert strengths_of(("sensor_lag",)) == strengths_of({"sensor_lag": 1.0})
    assert strengths_of("sensor_lag=0.2") == strengths_of({"sensor_lag": 0.2})
    with pytest.raises(ConfigError, match="unknown effect"):
        strengths_of(["sensor-lag"])
    with pytest.raises(ConfigError, match="must be a number"):
        parse_effects("sensor_lag=strong")
    with pytest.raises(ConfigError, match="out of range"):
        parse_effects("sensor_lag=1.6")
    with pytest.raises(ConfigError, match="out of range"):
        strengths_of({"slipstream": -0.1})


def test_strength_zero_is_the_mild_baseline():
    rng = lambda: np.random.default_rng(11)  # noqa: E731
    base = make_effects((), rng())
    assert make_effects({n: 0.0 for n in EFFECT_NAMES}, rng()) == base
    mild = dict(base.mild)
    for name, value in base.params().items():
        if name in mild:
            assert value == pytest.approx(mild[name], rel=1e-12), name
    assert base.active == () and base.lens_transmission == 1.0


def test_strength_one_is_the_strong_level():
    e = make_effects(EFFECT_NAMES, np.random.default_rng(3))
    assert e.crown_sigma_base == pytest.approx(0.5) and e.knee_gain == pytest.approx(0.40)
    assert e.slip_fraction_laps == pytest.approx(0.5) and e.slip_reduction == pytest.approx(0.3)
    assert e.ir_lag_s == pytest.approx(0.35) and e.emissivity_set == pytest.approx(1.0)
    assert e.k_z == pytest.approx(0.4 * dict(e.mild)["k_z"])
    mu = MuLaw(e.mu_deficit, e.mu_gain, e.mu_t_mid, e.mu_t_width)
    # The carbon-carbon law of the independent generator: 0.80 at 150, 1.15 at 600 degC.
    assert mu.ratio(150.0) == pytest.approx(0.80, abs=0.01)
    assert mu.ratio(600.0) == pytest.approx(1.15, abs=0.01)


# Direction in which each strength-driven parameter moves (+1 up, -1 down).
_DIRECTION = {
    "crown_sigma_base": 1,
    "crown_sigma_event": 1,
    "knee_gain": 1,
    "slip_fraction_laps": 1,
    "slip_reduction": 1,
    "mu_deficit": 1,
    "mu_gain": 1,
    "k_z": -1,
    "ir_lag_s": 1,
    "emissivity_set": 1,
}


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), s1=st.floats(0.0, 1.5), s2=st.floats(0.0, 1.5))
def test_parameters_monotone_in_strength(seed, s1, s2):
    lo, hi = sorted((s1, s2))
    a = make_effects({n: lo for n in EFFECT_NAMES}, np.random.default_rng(seed))
    b = make_effects({n: hi for n in EFFECT_NAMES}, np.random.default_rng(seed))
    for name, sign in _DIRECTION.items():
        assert sign * (getattr(b, name) - getattr(a, name)) >= -1e-12, name
    # The radiance ratio the pyrometer inverts keeps falling beyond strength 1.
    assert b.lens_transmission / b.emissivity_set <= a.lens_transmission / a.emissivity_set
    # mu(T): the cold deficit and the hot gain both grow, and the law stays monotone.
    t = np.linspace(20.0, 1000.0, 200)
    for e in (a, b):
        r = MuLaw(e.mu_deficit, e.mu_gain, e.mu_t_mid, e.mu_t_width).ratio(t)
        assert np.all(np.diff(r) > 0) and r[0] < 1.0 < r[-1]
    ra = MuLaw(a.mu_deficit, a.mu_gain, a.mu_t_mid, a.mu_t_width).ratio(t)
    rb = MuLaw(b.mu_deficit, b.mu_gain, b.mu_t_mid, b.mu_t_width).ratio(t)
    assert rb[0] <= ra[0] + 1e-12 and rb[-1] >= ra[-1] - 1e-12


def test_mild_baseline_varies_with_seed_within_its_range():
    draws = [make_effects((), np.random.default_rng(s)) for s in range(40)]
    k_z = np.array([e.k_z for e in draws])
    assert 10.5 <= k_z.min() and k_z.max() <= 13.5 and k_z.std() > 0.5
    lag = np.array([e.ir_lag_s for e in draws])
    assert 0.03 <= lag.min() and lag.max() <= 0.06 and np.unique(lag).size == 40
    assert all(0.02 <= e.mu_deficit <= 0.05 and 0.74 <= e.knee_frac <= 0.86 for e in draws)
    assert make_effects(()) == make_effects(())  # without a generator: mid-range values
    assert make_effects(()).k_z == pytest.approx(np.sqrt(10.5 * 13.5))


def test_random_strengths_within_range_and_reproducible():
    a = random_strengths(np.random.default_rng(5))
    assert a == random_strengths(np.random.default_rng(5))
    assert a != random_strengths(np.random.default_rng(6))
    assert list(a) == list(EFFECT_NAMES)
    assert all(0.5 <= v <= 1.3 and round(v, 2) == v for v in a.values())
    b = random_strengths(np.random.default_rng(5), ["sensor_lag"], low=0.2, high=0.4)
    assert list(b) == ["sensor_lag"] and 0.2 <= b["sensor_lag"] <= 0.4
    assert strengths_of(b)["slipstream"] == 0.0
    with pytest.raises(ConfigError):
        random_strengths(np.random.default_rng(5), low=0.5, high=2.0)
    with pytest.raises(ConfigError, match="unknown effect"):
        random_strengths(np.random.default_rng(5), ["nope"])


# --- effect signatures in the simulated session -------------------------------------------


def test_sensor_lag_delays_ir_only(runs):
    base, lag = runs["base"], runs["sensor_lag"]
    assert _same_truth(base, lag)
    assert _same_channel(base, lag, "brake_pressure_front")
    assert _fitted_lag(base) < 0.12
    assert 0.28 < _fitted_lag(lag) < 0.42
    assert _meta(lag)["effect_params"]["ir_lag_s"] == pytest.approx(0.35)


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
    base, knee = runs["base"], runs["h_speed_knee"]
    tk = _truth(knee)
    clean = ~tk.slipstream.to_numpy()
    ratio = tk.h.to_numpy(np.float64) / _h_without_knee_or_slip(knee)
    law = _meta(knee)["h_law"]
    slow = tk.speed.to_numpy() / 3.6 < law["knee_frac"] * law["v_ref_m_s"]
    assert np.allclose(ratio[slow & clean], 1.0, rtol=1e-5)
    assert np.allclose(ratio[clean], _knee_factor(knee)[clean], rtol=1e-5)
    assert law["knee_gain"] == pytest.approx(0.40)
    assert ratio[clean & (tk.speed.to_numpy() > 330.0)].min() > 1.15
    assert _meta(base)["h_law"]["knee_gain"] < 0.07
    assert tk.spot3.max() < _truth(base).spot3.max()  # extra cooling at top speed


def test_slipstream_reduces_h_on_flagged_straights_only(runs):
    base, slip = runs["base"], runs["slipstream"]
    ts = _truth(slip)
    flag = ts.slipstream.to_numpy()
    assert flag.any()
    ratio = ts.h.to_numpy(np.float64) / (_h_without_knee_or_slip(slip) * _knee_factor(slip))
    red = _meta(slip)["effect_params"]["slip_reduction"]
    assert red == pytest.approx(0.30)
    assert np.all((ratio[flag] > 1 - 1.2 * red - 1e-5) & (ratio[flag] < 1 - 0.8 * red + 1e-5))
    assert np.allclose(ratio[~flag], 1.0, rtol=1e-5)
    assert (ts.speed[flag] > 150).all()
    assert (ts.q_brake[flag] == 0).all()
    # Mild: a few per cent on the laps that follow, if any.
    tb = _truth(base)
    rb = tb.h.to_numpy(np.float64) / (_h_without_knee_or_slip(base) * _knee_factor(base))
    assert rb.min() > 1 - 1.2 * 0.07 - 1e-5


def test_friction_temperature_law_and_pressure(runs):
    base, fric = runs["base"], runs["friction_temperature"]
    tf, tb = _truth(fric), _truth(base)
    assert tf.mu_ratio.max() - tf.mu_ratio.min() > 0.25  # cold deficit to hot gain
    assert tb.mu_ratio.max() - tb.mu_ratio.min() < 0.1
    meta = _meta(fric)
    mu = MuLaw(**{k: meta["mu_law"][k] for k in ("deficit", "gain", "t_mid", "t_width")})
    assert mu.ratio(150.0) == pytest.approx(0.80, abs=0.01)
    # The delivered torque follows mu at the line pressure; the rider squeezes harder
    # when mu is low, so the logged pressure carries 1/mu with the rider's lag.
    chain = meta["model_errors"]
    braking = (tf.q_brake > 5000).to_numpy()
    x = tf.p_line_bar.to_numpy(np.float64)[braking] - chain["knock_back_bar"]
    k_eff = tf.brake_torque.to_numpy(np.float64)[braking] / x
    assert np.corrcoef(k_eff, tf.mu_ratio[braking])[0, 1] > 0.8
    cold, hot = tf.mu_ratio[braking] < 0.95, tf.mu_ratio[braking] > 1.08
    assert cold.sum() > 10 and hot.sum() > 10
    over = (tf.q_brake_nominal / tf.q_brake).to_numpy()[braking]
    assert np.median(over[cold]) > np.median(over[hot]) + 0.1


def test_thickness_gradient_surface_far_hotter_than_mid(runs):
    base, thick = _truth(runs["base"]), _truth(runs["thickness_gradient"])
    gap_b = (base.spot3 - base.spot3_mid).max()
    gap_t = (thick.spot3 - thick.spot3_mid).max()
    assert 50.0 < gap_b < 250.0  # k_z near the datasheet's 12 W/(m K)
    assert gap_t > 1.8 * gap_b and gap_t > 250.0
    m = _meta(runs["thickness_gradient"])
    assert m["k_z_w_mk"] == pytest.approx(0.4 * m["effect_mild"]["k_z"])
    assert 10.5 <= _meta(runs["base"])["k_z_w_mk"] <= 13.5


def test_power_distribution_strongly_non_uniform_and_corner_dependent(runs):
    base, pd_ = _truth(runs["base"]), _truth(runs["power_distribution"])
    w = ["w1", "w2", "w3"]
    assert (base[w].dropna() - 1 / 3).abs().to_numpy().max() < 0.12
    wd = pd_[w].dropna()
    assert (wd - 1 / 3).abs().to_numpy().max() > 0.2
    assert np.allclose(wd.sum(axis=1), 1.0, atol=1e-5)
    braking = pd_.q_brake > 0
    spread = lambda t: (t[SPOTS[1:]].max(axis=1) - t[SPOTS[1:]].min(axis=1))[braking].mean()  # noqa: E731
    assert spread(pd_) > 1.5 * spread(base)


@pytest.fixture(scope="module")
def half() -> dict[str, SimResult]:
    """Two effects at strength 0.5, same seed and track as ``runs``."""
    cfg = dict(track="mugello-like", laps=2, seed=3)
    return {
        n: simulate(SimConfig(**cfg, effects={n: 0.5}))
        for n in ("thickness_gradient", "friction_temperature")
    }


def test_signatures_grow_monotonically_with_strength(runs, half):
    def gap(r):
        t = _truth(r)
        return (t.spot3 - t.spot3_mid).max()

    def mu_range(r):
        t = _truth(r)
        return t.mu_ratio.max() - t.mu_ratio.min()

    for name, measure in (("thickness_gradient", gap), ("friction_temperature", mu_range)):
        values = [measure(runs["base"]), measure(half[name]), measure(runs[name])]
        assert values[0] < values[1] < values[2], name
    # Other effects keep their mild draw: the same k_z at every friction strength.
    assert _meta(half["friction_temperature"])["k_z_w_mk"] == _meta(runs["base"])["k_z_w_mk"]


# --- the brake chain and its model errors ------------------------------------------------


def test_model_errors_recorded_and_used(runs):
    base = runs["base"]
    chain = _meta(base)["model_errors"]
    assert 3.0 <= abs(chain["torque_per_bar_error_pct"]) <= 6.0
    assert 3.0 <= abs(chain["heat_share_error_pct"]) <= 6.0
    assert chain["torque_per_bar_datasheet"] == 40.0 and chain["heat_share_datasheet"] == 0.9
    assert chain["model_errors"] is True
    t = _truth(base)
    braking = (t.q_brake > 20_000).to_numpy()
    # The datasheet formula on the true line pressure misses the true heat by the
    # model errors (times mu and the caliper's play and nonlinearity): not exact.
    over = (t.q_brake_nominal / t.q_brake).to_numpy()[braking]
    expected = 0.9 * 40.0 / (chain["heat_share"] * chain["torque_per_bar"])
    assert np.median(over) == pytest.approx(expected, rel=0.06)
    assert np.percentile(over, 95) - np.percentile(over, 5) > 0.02


def test_without_model_errors_the_datasheet_is_true():
    r = simulate(SimConfig(track="tight-like", laps=1, seed=4, model_errors=False))
    chain = _meta(r)["model_errors"]
    assert chain["torque_per_bar"] == 40.0 and chain["heat_share"] == 0.9
    assert chain["sensor_offset_bar"] == 0.0 and chain["torque_nonlinearity"] == 0.0
    disc = load_disc("cc-340-8")
    ideal = draw_brake_chain(disc, np.random.default_rng(9), False)
    real = draw_brake_chain(disc, np.random.default_rng(9), True)
    assert ideal.rider_lag_s == real.rider_lag_s and ideal.modulation == real.modulation
    assert real.torque_per_bar != 40.0


def test_sessions_of_one_bike_share_its_hardware():
    disc = load_disc("cc-340-8")

    def chain(seed, bike):
        return draw_brake_chain(disc, np.random.default_rng(seed), True,
                                np.random.default_rng(bike))

    a, b, c = chain(1, 77), chain(2, 77), chain(1, 78)
    for k in ("torque_per_bar", "heat_share", "torque_nonlinearity", "sensor_gain"):
        assert getattr(a, k) == getattr(b, k) and getattr(a, k) != getattr(c, k), k
    assert a.sensor_offset_bar != b.sensor_offset_bar  # zeroed again every session
    assert a.sensor_offset_bar == c.sensor_offset_bar and a.rider_lag_s == c.rider_lag_s


def test_caliper_play_gives_hysteresis(fast):
    t = _truth(fast)
    p = t.p_line_bar.to_numpy(np.float64)
    k = t.brake_torque.to_numpy(np.float64) / t.mu_ratio.to_numpy(np.float64)
    dp = np.gradient(p, t.time.to_numpy())
    band = (p > 4.0) & (p < 8.0)
    rising, falling = band & (dp > 5.0), band & (dp < -5.0)
    assert rising.sum() > 10 and falling.sum() > 10
    # At the same line pressure the pads clamp harder on release than on apply.
    assert np.median(k[falling] / p[falling]) > np.median(k[rising] / p[rising]) * 1.02


# --- determinism and writers -----------------------------------------------------------


@pytest.mark.parametrize("ext", ["mcap", "parquet", "csv"])
def test_same_seed_same_bytes(tmp_path: Path, ext: str):
    cfg = SimConfig(track="tight-like", laps=1, seed=21, effects={"slipstream": 0.7})
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
            "sensor_lag=0.5,emissivity_error",
            "--out",
            str(out),
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["effects"] == {"sensor_lag": 0.5, "emissivity_error": 1.0}
    assert out.is_file() and (tmp_path / "run.truth.parquet").is_file()
    meta = json.loads(pq.read_schema(tmp_path / "run.truth.parquet").metadata[b"brakethermo_truth"])
    assert meta["effect_strengths"]["sensor_lag"] == 0.5
    assert meta["effect_strengths"]["emissivity_error"] == 1.0
    assert meta["effect_strengths"]["slipstream"] == 0.0
    mild_lag = meta["effect_mild"]["ir_lag_s"]
    assert meta["effect_params"]["ir_lag_s"] == pytest.approx(np.sqrt(mild_lag * 0.35))
    for arg, msg in (("nope", "unknown effect"), ("sensor_lag=x", "must be a number"),
                     ("sensor_lag=2", "out of range")):
        bad = CliRunner().invoke(app, ["simulate", "--effects", arg, "--out", str(out)])
        assert bad.exit_code == 1 and msg in bad.output, arg
        assert "Traceback" not in bad.output


@pytest.mark.parametrize("dt", [0.025, 0.0])
def test_a_thermal_step_the_rider_cannot_step_is_refused(dt: float) -> None:
    """0.025 s divides the 0.1 s grid but is 12.5 rider samples: it ran off the end of
    the rider's arrays (IndexError); now a clear error before any work."""
    with pytest.raises(ConfigError, match="thermal step"):
        simulate(SimConfig(laps=1, dt=dt))
