"""10 Hz resampling, spike rejection, gap reporting and laps: properties and exact cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.errors import DataError
from brakethermo.io.laps import laps_from_beacons
from brakethermo.io.resample import grid, hampel, resample, sort_checked

RATES = st.sampled_from([10.0, 20.0, 25.0, 50.0, 100.0, 200.0, 500.0])
DURATIONS = st.floats(min_value=2.0, max_value=30.0)
OFFSETS = st.floats(min_value=0.0, max_value=0.5)


def native(rate: float, duration: float, offset: float) -> np.ndarray:
    return offset + np.arange(int(duration * rate)) / rate


@settings(max_examples=60, deadline=None)
@given(rate=RATES, duration=DURATIONS, offset=OFFSETS,
       c=st.floats(min_value=-1e6, max_value=1e6, allow_nan=False))
def test_constant_stays_constant(rate: float, duration: float, offset: float, c: float) -> None:
    t = native(rate, duration, offset)
    out = resample(t, np.full(t.size, c), grid(t[-1])).values
    finite = out[np.isfinite(out)]
    assert finite.size >= len(out) - 6
    np.testing.assert_allclose(finite, c, rtol=1e-12, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(rate=RATES, duration=DURATIONS, offset=OFFSETS,
       a=st.floats(min_value=-100.0, max_value=100.0),
       b=st.floats(min_value=-50.0, max_value=50.0))
def test_ramp_stays_a_ramp(rate: float, duration: float, offset: float, a: float, b: float
                           ) -> None:
    t = native(rate, duration, offset)
    g = grid(t[-1])
    out = resample(t, a + b * t, g).values
    # Inside the data span the ramp is exact; outside it the edge is held half a bin out.
    inside = (g >= t[0]) & (g <= t[-1])
    np.testing.assert_allclose(out[inside], (a + b * g)[inside], rtol=1e-9, atol=1e-7)


@settings(max_examples=60, deadline=None)
@given(rate=st.sampled_from([50.0, 100.0, 500.0]), seconds=st.integers(5, 30),
       seed=st.integers(0, 2**32 - 1))
def test_mean_is_preserved(rate: float, seconds: int, seed: int) -> None:
    # Whole bins of a signal sampled from t = 0: the grid mean is the sample mean up to the
    # half-filled first and last bins.
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate) + 1) / rate
    v = 50.0 + 10.0 * rng.standard_normal(t.size)
    out = resample(t, v, grid(t[-1])).values
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out[1:-1].mean(), v[(t >= 0.05) & (t < t[-1] - 0.05)].mean(),
                               atol=0.05)
    np.testing.assert_allclose(out.mean(), v.mean(), atol=10.0 * 3.0 / np.sqrt(len(out)))


@settings(max_examples=30, deadline=None)
@given(phase=st.floats(min_value=0.0, max_value=2.0 * np.pi),
       freq=st.floats(min_value=28.0, max_value=32.0))
def test_high_frequency_is_attenuated_not_aliased(phase: float, freq: float) -> None:
    # A ~30 Hz sine at 500 Hz: the 0.1 s bin average (|H| = |sinc(0.1 f)| <= 0.07 here)
    # leaves almost nothing instead of folding it into 0-5 Hz.
    t = np.arange(0, 20.0, 1.0 / 500.0)
    out = resample(t, np.sin(2.0 * np.pi * freq * t + phase), grid(t[-1])).values[1:-1]
    assert np.abs(out).max() < 0.1
    assert (np.abs(np.fft.rfft(out)) / out.size).max() < 0.05


def test_nearest_sample_picking_would_alias() -> None:
    # 30.3 Hz folds to 0.3 Hz at full amplitude when every 50th sample is picked.
    t = np.arange(0, 20.0, 1.0 / 500.0)
    v = np.sin(2.0 * np.pi * 30.3 * t)
    picked = v[::50]
    assert np.abs(picked).max() > 0.9
    # (first and last grid points see only half a bin of data; the interior is the claim)
    assert np.abs(resample(t, v, grid(t[-1])).values[1:-1]).max() < 0.05


def test_low_frequency_passes() -> None:
    t = np.arange(0, 20.0, 1.0 / 500.0)
    out = resample(t, np.sin(2.0 * np.pi * 0.5 * t), grid(t[-1])).values
    np.testing.assert_allclose(out, np.sin(2.0 * np.pi * 0.5 * grid(t[-1])), atol=0.01)


def test_short_gap_bridged_long_gap_reported() -> None:
    t = np.arange(0, 30.0, 0.01)
    short = (t > 5.0) & (t < 5.6)
    long = (t > 10.0) & (t < 13.0)
    keep = ~(short | long)
    t, v = t[keep], 2.0 * t[keep]
    res = resample(t, v, grid(t[-1]), gap_limit_s=1.0)
    g = grid(t[-1])
    # the short gap is bridged linearly (exact for this ramp)
    sel = (g > 5.0) & (g < 5.6)
    np.testing.assert_allclose(res.values[sel], 2.0 * g[sel], rtol=1e-9)
    # the long gap is NaN and reported once
    assert len(res.gaps) == 1
    start, duration = res.gaps[0]
    assert start == pytest.approx(10.0) and duration == pytest.approx(3.0)
    inside = (g > 10.06) & (g < 12.95)
    assert np.isnan(res.values[inside]).all()
    assert np.isfinite(res.values[~((g > 10.0) & (g < 13.0))]).all()
    # a larger limit bridges it
    assert resample(t, v, g, gap_limit_s=5.0).gaps == ()


def test_channel_starting_late_reports_leading_gap() -> None:
    t = np.arange(10.0, 20.0, 0.02)
    res = resample(t, np.ones(t.size), grid(20.0))
    assert res.gaps[0] == pytest.approx((0.0, 10.0))
    assert np.isnan(res.values[:99]).all() and np.isfinite(res.values[100:-1]).all()


def test_slow_channel_own_period_is_not_a_gap() -> None:
    t = np.arange(0.0, 60.0, 2.0)  # 0.5 Hz ambient
    res = resample(t, 20.0 + 0.01 * t, grid(t[-1]))
    assert res.gaps == ()
    assert res.rate_hz == pytest.approx(0.5)
    assert np.isfinite(res.values).all()


def test_hampel_rejects_isolated_spikes_only() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0, 20.0, 0.02)
    clean = 400.0 + 150.0 * np.sin(2 * np.pi * 0.1 * t) + rng.normal(0, 1.0, t.size)
    spiky = clean.copy()
    where = np.array([100, 300, 301, 650])  # 300/301 a 2-sample spike
    spiky[where] += np.array([250.0, -300.0, -280.0, 400.0])
    filtered, count = hampel(spiky)
    assert count == 4
    np.testing.assert_allclose(filtered[where], clean[where], atol=8.0)
    unchanged = np.setdiff1d(np.arange(t.size), where)
    assert (filtered[unchanged] == spiky[unchanged]).mean() > 0.995
    assert hampel(clean)[1] <= 2


def test_hampel_keeps_fast_braking_rise() -> None:
    t = np.arange(0, 4.0, 0.02)
    rise = np.where(t < 1.0, 300.0, 300.0 + 120.0 * (t - 1.0))  # 120 degC/s in braking
    assert hampel(rise)[1] == 0


def test_duplicate_timestamps_rejected_with_count_and_first_time() -> None:
    t = np.array([0.0, 0.1, 0.2, 0.2, 0.3, 0.5, 0.5])
    with pytest.raises(DataError, match=r"2 duplicate timestamp\(s\), the first at t = 0\.2"):
        sort_checked(t, np.zeros(t.size), path="f.csv", channel="vFront")


def test_sort_checked_sorts() -> None:
    t, v = sort_checked(np.array([0.3, 0.1, 0.2]), np.array([3.0, 1.0, 2.0]), path=None,
                        channel="x")
    assert t.tolist() == [0.1, 0.2, 0.3] and v.tolist() == [1.0, 2.0, 3.0]


def test_laps_from_beacons() -> None:
    g = grid(100.0)
    laps, lap = laps_from_beacons(np.array([12.3, 55.0]), np.array([1.0, 2.0]), g, 100.0)
    assert [(x.lap, x.start_s, x.duration_s) for x in laps] == [
        (0, 0.0, 12.3), (1, 12.3, pytest.approx(42.7)), (2, 55.0, 45.0)]
    assert lap[122] == 0 and lap[123] == 1 and lap[549] == 1 and lap[550] == 2


def test_a_log_begun_inside_a_lap_marks_its_first_stretch_cut() -> None:
    """The first beacon numbers lap 3: before it the log ran inside lap 2 (it began
    mid-lap). That stretch stays lap 0, as an out-lap does (no flying lap: its lap distance
    does not run from the line), but marked cut and partial, never a whole lap."""
    from brakethermo.results.laps import partial_laps

    g = grid(400.0)
    laps, lap = laps_from_beacons(np.array([90.6, 190.0, 290.0]), np.array([3.0, 4.0, 5.0]),
                                  g, 400.0)
    assert [(x.lap, x.cut_start) for x in laps] == [
        (0, True), (3, False), (4, False), (5, False)]
    assert lap[0] == 0 and lap[905] == 0 and lap[906] == 3
    assert partial_laps(laps) == {0}  # 90.6 s of ~100 s laps: still not a lap
    laps, _ = laps_from_beacons(np.array([12.3, 55.0]), np.array([1.0, 2.0]), g, 100.0)
    assert laps[0].lap == 0 and not laps[0].cut_start and partial_laps(laps) == set()


def test_no_beacon_is_one_lap_and_beacon_at_zero_has_no_outlap() -> None:
    g = grid(50.0)
    laps, lap = laps_from_beacons(np.empty(0), np.empty(0), g, 50.0)
    assert [(x.lap, x.start_s, x.duration_s) for x in laps] == [(0, 0.0, 50.0)]
    assert (lap == 0).all()
    laps, lap = laps_from_beacons(np.array([0.0, 20.0]), np.array([3.0, 4.0]), g, 50.0)
    assert [x.lap for x in laps] == [3, 4] and lap[0] == 3 and lap[-1] == 4


def test_bad_beacon_value() -> None:
    with pytest.raises(DataError, match="not a lap number"):
        laps_from_beacons(np.array([1.0]), np.array([1.5]), grid(5.0), 5.0)


def test_a_clock_that_jumps_back_is_refused_where_rows_are_in_time_order() -> None:
    """A logger clock reset (the second half 300.0004 s earlier) was sorted into the first
    half: two recordings interleaved into one session, exit 0. A few samples out of order
    are still sorted, and MCAP, whose messages may be out of log-time order, is not
    judged so."""
    t = np.concatenate([np.arange(0.0, 600.0, 0.1), np.arange(0.0, 600.0, 0.1) + 299.9996])
    with pytest.raises(DataError, match=r"time goes back by 299\.9\d+ s after sample 6000"):
        sort_checked(t, np.zeros(t.size), path="f.csv", channel="vFront")
    sorted_t, _ = sort_checked(t, np.zeros(t.size), path="f.mcap", channel="vFront",
                               time_ordered=False)
    assert (np.diff(sorted_t) > 0).all()
    jitter = np.array([0.0, 0.1, 0.3, 0.2, 0.4])
    assert sort_checked(jitter, jitter, path="f.csv", channel="x")[0].tolist() == [
        0.0, 0.1, 0.2, 0.3, 0.4]


def test_a_csv_cut_inside_its_last_row_drops_that_row_and_says_so(tmp_path) -> None:
    """A copy cut mid-number read 18 rad/s for 185.15 in the last row, without a word."""
    from brakethermo.io.csv_reader import read_csv

    path = tmp_path / "cut.csv"
    path.write_text("time [s],wheel_speed [rad/s]\n0.0,185.0\n0.1,185.1\n0.2,18")
    raw = read_csv(path)
    assert raw.channels[0].v.tolist() == [185.0, 185.1]
    assert any("ends inside its last row" in w for w in raw.warnings)
    path.write_text("time [s],wheel_speed [rad/s]\n0.0,185.0\n0.1,185.1\n")
    assert read_csv(path).warnings == ()


def test_a_log_ended_inside_its_last_lap_marks_that_lap_cut() -> None:
    """No beacon closes a session's last lap. An independent generator's session ended in
    the pits 55 % round it, slowly enough to last a lap's time: it was given a lap time
    and used as a flying lap. The distance ridden in it (speed integrated) tells."""
    from brakethermo.io.laps import mark_cut_end
    from brakethermo.results.laps import partial_laps

    t = grid(400.0, 0.1)
    laps, lap = laps_from_beacons(np.array([0.0, 100.0, 200.0, 300.0]),
                                  np.array([0.0, 1.0, 2.0, 3.0]), t, 400.0)
    speed = np.full(t.size, 40.0)  # 4 km laps
    speed[lap == 3] = 22.0  # the last "lap": 2.2 km in as long as a lap, to the pits
    cut = mark_cut_end(laps, lap, speed, 0.1)
    assert [x.cut_end for x in cut] == [False, False, False, True]
    assert partial_laps(cut) == {3} and partial_laps(laps) == set()
    speed[lap == 3] = 39.0  # a whole lap that ended at the line: kept
    assert not mark_cut_end(laps, lap, speed, 0.1)[-1].cut_end
    assert mark_cut_end(laps, lap, None, 0.1) == laps  # no speed: nothing to tell
