"""estimate on simulated sessions: contract, accuracy against truth, robustness."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from brakethermo.errors import DataError
from brakethermo.io.load import load_session
from brakethermo.pipelines.estimate import (
    EstimateOptions,
    estimate_from_session,
    estimate_session,
    write_estimate,
)
from brakethermo.pipelines.truth_score import read_truth, score_against_truth


@pytest.fixture(scope="module")
def estimated(sim_race_session, identified):
    return estimate_session(sim_race_session[0], EstimateOptions(h_law=identified[1]))


def test_outputs_follow_the_contract(estimated, tmp_path):
    folder = write_estimate(estimated, tmp_path)
    table = pq.read_table(folder / "estimate.parquet")
    names = table.column_names
    for col in ("time", "lap", "contact_avg", "contact_avg_std",
                *[f"spot{i}{s}" for i in range(1, 5) for s in ("", "_std")]):
        assert col in names
    nodes = [n for n in names if n.startswith("node_")]
    assert len(nodes) == estimated.summary["run"]["nodes"]
    radii = [float(table.schema.field(n).metadata[b"radius_m"]) for n in nodes]
    assert np.all(np.diff(radii) > 0) and radii[0] == pytest.approx(0.100)
    time = table.column("time").to_numpy()
    assert time[0] == 0.0 and np.allclose(np.diff(time), 0.1)
    summary = json.loads((folder / "summary.json").read_text())
    lap = summary["laps"][-1]
    assert {"lap_time_s", "peak", "time_in_window_s", "mean_contact_c"} <= set(lap)
    assert summary["run"]["smoother"] is True and summary["run"]["wall_time_s"] > 0
    # the hottest radius with its band, from the smoother's node variances
    frame = estimated.frame
    face = frame[nodes].to_numpy()
    np.testing.assert_array_equal(frame["hottest_radius"], face.max(axis=1))
    std = frame["hottest_radius_std"].to_numpy()
    assert np.all(std > 0) and np.all(np.isfinite(std))
    # no narrower than the nearest spot's filter spread would allow: the face nodes'
    # variances carry the calibration and the crown terms the spots do
    assert np.median(std) >= 0.5 * np.median(frame["spot3_std"])
    lo, hi = lap["hottest"]["time_above_window_band_s"]
    assert lo <= lap["hottest"]["time_above_window_s"] <= hi


def test_beats_single_spot_baseline_against_truth(estimated, sim_race_session):
    truth = read_truth(sim_race_session[1])
    measured = estimated.session.values("disc_temp_spot3")
    sc = score_against_truth(estimated.frame, truth, measured, estimated.open_loop)
    rows = {r["method"]: r for r in sc["table"]}
    # README: ~0.2-0.3x over the reporting seeds' 4-lap races with mild effects; this
    # 2-lap race (seed 4243, 5 % torque and heat-share errors the estimator cannot
    # know) reaches 0.35x (0.51x with k_z and slipstream forced on)
    assert sc["contact_ratio"]["smoother"] < 0.45
    assert rows["smoother"]["spot4"] < rows["single-spot"]["spot4"]
    assert abs(sc["peak_spot3"]["mean_abs_pct"]) < 1.5  # README: 0.3-1.1 % on model effects
    # README: the 95 % band covers the truth at the unmeasured spots. Their bands admit a
    # crown balance unlike the test session's (pipelines/crown_band), which this race's
    # pads do not have: they cover all but a few samples (99.9 %)
    cov = [sc["coverage95"][s] for s in ("spot1", "spot2", "spot4")]
    assert np.mean(cov) >= 0.95
    # the contact band, which that term leaves as it was, stays calibrated and not wide
    # (the race decides its online effects, identify-h calibrates the noise for that): 98.6 %
    assert 0.85 <= sc["coverage95_contact"] <= 0.997
    assert min(cov) >= 0.75


def test_scores_itself_on_a_multi_spot_session(estimated):
    sc = estimated.scores
    methods = [r["method"] for r in sc["table"]]
    assert methods == ["smoother", "filter", "open-loop 1D-FE", "single-spot"]
    assert set(sc["coverage95"]) == {"spot1", "spot2", "spot4"}


def test_layered_model_beats_one_layer(estimated, sim_race_session, identified):
    one = estimate_session(sim_race_session[0], EstimateOptions(h_law=identified[1], layers=1))
    truth = read_truth(sim_race_session[1])
    measured = estimated.session.values("disc_temp_spot3")
    r3 = score_against_truth(estimated.frame, truth, measured)["contact_ratio"]["smoother"]
    r1 = score_against_truth(one.frame, truth, measured)["contact_ratio"]["smoother"]
    assert r3 < r1


def test_smoother_in_windows_gives_the_same_estimate(estimated, sim_race_session, identified,
                                                    monkeypatch):
    """A mesh whose gains do not fit is smoothed in windows, in parallel: same answer."""
    from brakethermo.estimation import urts

    assert estimated.summary["run"]["smoother_windows"] == 1
    monkeypatch.setattr(urts, "DEFAULT_MAX_STORE_BYTES", 2**20)  # ~20 windows
    res = estimate_session(sim_race_session[0], EstimateOptions(h_law=identified[1], workers=2))
    assert res.summary["run"]["smoother_windows"] > 10
    assert res.summary["run"]["workers"] == 2
    cols = [c for c in estimated.frame.columns if c.startswith(("spot", "contact", "node_"))]
    diff = (res.frame[cols] - estimated.frame[cols]).abs().to_numpy().max()
    assert diff < 1e-6  # degC, against a 95 % band tens of degC wide


def test_filter_only_has_no_smoother_row(sim_race_session, identified):
    res = estimate_session(sim_race_session[0],
                           EstimateOptions(h_law=identified[1], smoother=False))
    assert res.summary["run"]["smoother"] is False
    assert res.scores["table"][0]["method"] == "filter"


def test_dropout_spike_and_bad_start_do_not_derail(sim_race_session, identified):
    session = load_session(sim_race_session[0])
    frame = session.frame.copy()
    y = frame["disc_temp_spot3"].to_numpy().copy()
    k0 = int(np.flatnonzero(np.isfinite(y))[0])
    y[k0] = 20.0  # a deliberately bad first reading: the filter starts 300+ degC off
    mid = len(y) // 2
    y[mid : mid + 200] = np.nan  # a 20 s sensor dropout
    y[mid + 400] += 400.0  # a spike the reader's Hampel filter did not catch
    frame["disc_temp_spot3"] = y
    broken = type(session)(**{**session.__dict__, "frame": frame})
    res = estimate_from_session(broken, EstimateOptions(h_law=identified[1]))
    truth = read_truth(sim_race_session[1])
    est = res.frame["spot3"].to_numpy()
    assert np.isfinite(est).all()
    n = min(len(est), len(truth))
    late = slice(mid + 600, n)
    err = est[late] - truth["spot3"].to_numpy()[late]
    assert np.sqrt(np.mean(err**2)) < 25.0
    # the bad start, dropout and spike are absorbed without one covariance repair
    assert res.summary["run"]["covariance_repairs"] == 0


def test_a_pyrometer_slower_than_the_grid_weighs_each_reading_once(
        estimated, sim_race_session, identified, tmp_path):
    """A 2 Hz pyrometer interpolated onto the 10 Hz grid: its noise taken from the grid's
    second differences came out near 0 (floor 0.5 degC), five interpolated points per
    reading counted as five readings, and the mean NIS of 6.5 read as 'IMPLAUSIBLE
    RESULT ... brake pressure, wheel speed'."""
    import pyarrow as pa

    table = pq.read_table(sim_race_session[0])
    frame = table.to_pandas()
    ir = [c for c in frame.columns if c.startswith("disc_temp")]
    have = np.flatnonzero(frame[ir[0]].notna().to_numpy())
    rate = 1.0 / np.median(np.diff(frame["time"].to_numpy()[have]))
    drop = np.setdiff1d(have, have[:: round(float(rate) / 2.0)])
    frame.loc[frame.index[drop], ir] = np.nan
    slow = tmp_path / "slow_ir.parquet"
    pq.write_table(pa.Table.from_pandas(frame, schema=table.schema, preserve_index=False), slow)
    res = estimate_session(slow, EstimateOptions(h_law=identified[1]))
    run, native = res.summary["run"], estimated.summary["run"]
    assert not any("IMPLAUSIBLE" in w for w in run["warnings"])
    assert any("logged at 2.0" in w and "each reading counts once" in w
               for w in run["warnings"])
    assert "sqrt(5)" in run["sigma_meas_source"]
    # a 2 Hz reading is one raw sample; a native one (20 Hz) the mean of two in its bin
    raw = run["sigma_meas_c"] / np.sqrt(5)
    assert raw / np.sqrt(2) == pytest.approx(native["sigma_meas_c"], rel=0.3)
    assert 0.2 < run["mean_nis"] < 2.0


def test_spot_not_logged_is_a_clear_error(sim_race_session, identified, tmp_path):
    from brakethermo.sim.session import SimConfig, simulate, write_simulation

    path, _ = write_simulation(simulate(SimConfig(laps=1, sensor="single", seed=8)),
                               tmp_path / "single.parquet")
    with pytest.raises(DataError, match="spot 2"):
        estimate_session(path, EstimateOptions(h_law=identified[1], spot=2))
    res = estimate_session(path, EstimateOptions(h_law=identified[1]))
    assert res.scores is None and np.isfinite(res.frame["contact_avg"]).all()


def test_a_race_too_short_to_decide_its_online_effects_says_so() -> None:
    """A race without laps (no beacon) left its online effects off with the reason only in
    summary.json (an independent generator's race: 0.26x instead of 0.14x)."""
    from types import SimpleNamespace

    from brakethermo.pipelines.estimate import undecided_warning

    short = SimpleNamespace(facts={"rule": "not decided: fewer than two flying laps; online"
                                           " effects left off"})
    said = undecided_warning(short)  # type: ignore[arg-type]
    assert len(said) == 1 and "lap_beacon" in said[0]
    assert undecided_warning(SimpleNamespace(facts={"rule": "switched on when"})) == []
    assert undecided_warning(None) == []
