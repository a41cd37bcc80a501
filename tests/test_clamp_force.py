"""clamp-force: eq. 6-8 against exact data, the filters, targets on unseen sessions, the CLI."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.estimation.kf import kalman_filter, kalman_filter_tv
from brakethermo.io.writers import Channel, SessionData, write_session
from brakethermo.models.clamp_force import (
    Q_SCALES,
    eq7_choice,
    estimate,
    fusion_check,
    motor_rates,
    train,
)
from brakethermo.numeric import rmse
from brakethermo.pipelines import clamp_force as cfp
from brakethermo.results.clamp_force import estimator_series, scored_force
from brakethermo.rigs.emb import (
    TorqueBalance,
    dynamic_stiffness,
    fit_dynamic_stiffness,
    fit_torque_balance,
    ml_fusion,
    sensor_delagged,
    torque_balance_force,
)
from brakethermo.sim.emb import EmbCaliper, simulate_emb, write_emb_simulation

TS = 1e-3


def _arrays(sim):
    ch = {c.name: c.value for c in sim.session.channels}
    return ch["motor_angle"], ch["motor_current"], ch.get("clamp_force", np.nan) * 1e3


def test_fits_recover_exact_models() -> None:
    rng = np.random.default_rng(1)
    theta = np.cumsum(rng.normal(0, 0.02, 5000)) + 4.0
    beta = np.array([30.0, 20.0, 600.0, -100.0])
    F = dynamic_stiffness(theta, 0.6, beta)
    ds = fit_dynamic_stiffness(theta, F, TS)
    assert ds.alpha0 == pytest.approx(0.6, rel=1e-3)
    np.testing.assert_allclose(ds.beta, beta, rtol=2e-3, atol=1e-3)
    p = TorqueBalance(gamma=1.6e-3, inertia=6e-4, mu=2.4e-4, offset=1.0, bias=0.4)
    from brakethermo.rigs.emb import motor_rates

    omega, acc = motor_rates(theta, TS)
    sg = np.sign(omega)
    current = (p.gamma + p.mu * sg) * F + p.inertia * acc + p.offset * sg + p.bias
    q = fit_torque_balance(current, theta, TS, F)
    np.testing.assert_allclose(
        [q.gamma, q.inertia, q.mu, q.offset, q.bias],
        [p.gamma, p.inertia, p.mu, p.offset, p.bias],
        rtol=1e-6,
    )
    np.testing.assert_allclose(torque_balance_force(current, theta, TS, q), F, rtol=1e-6)


def test_ml_fusion_weights() -> None:
    assert ml_fusion(np.array([1.0]), np.array([3.0]), 1.0, 1.0)[0] == pytest.approx(2.0)
    assert ml_fusion(np.array([1.0]), np.array([3.0]), 0.0, 1.0)[0] == pytest.approx(1.0)


def test_compiled_kf_matches_reference_and_explicit_time_varying_loop() -> None:
    rng = np.random.default_rng(3)
    K, n = 200, 2
    A = np.eye(n) + rng.normal(0, 0.2, (K, n, n))
    Q, H, R = np.eye(n) * 0.1, np.array([[1.0, 0.3]]), np.array([[0.5]])
    y, b = rng.normal(size=(K, 1)), rng.normal(size=(K, n))
    y[17] = np.nan
    ref = kalman_filter(A[0], Q, H, R, np.zeros(n), np.eye(n), y, b)
    got = kalman_filter_tv(A[0], Q, H, R, np.zeros(n), np.eye(n), y, b)
    np.testing.assert_allclose(got.x_filt, ref.x_filt, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.loglik, ref.loglik, rtol=1e-10, atol=1e-12)
    tv = kalman_filter_tv(A, Q, H, R, np.zeros(n), np.eye(n), y, b)
    x, P = np.zeros(n), np.eye(n)
    for k in range(K):
        if k:
            x, P = A[k - 1] @ x + b[k - 1], A[k - 1] @ P @ A[k - 1].T + Q
        if np.isfinite(y[k]).all():
            S = H @ P @ H.T + R
            G = P @ H.T / S[0, 0]
            x, P = x + (G @ (y[k] - H @ x)), P - G @ S @ G.T
    np.testing.assert_allclose(tv.x_filt[-1], x, rtol=1e-10)


@pytest.fixture(scope="module")
def trained():
    th, cur, F = _arrays(simulate_emb("nominal", seed=6001, duration_s=40.0))
    return train(th, cur, F, TS)


def _truth(sim) -> np.ndarray:
    return sim.truth.column("clamp_force").to_numpy() * 1e3


def test_targets_on_unseen_sessions(trained) -> None:
    """KF ≥ 15 % below stiffness and below ML; worn error after re-training on 20 s within
    1.3x nominal on average over the seeds (the worn gearing's extra friction makes single
    sessions scatter up to ~1.4x, see the README figures); heating held by the adaptive KF."""
    ratios = []
    for seed in (6101, 6102, 6103):
        nominal = simulate_emb("nominal", seed=seed, duration_s=20.0)
        th, cur, _ = _arrays(nominal)
        e = estimate(trained, th, cur, TS)
        truth = _truth(nominal)
        kf, ml, ds = rmse(e.kf, truth), rmse(e.ml_fusion, truth), rmse(e.stiffness, truth)
        assert kf <= 0.85 * ds
        assert kf < ml
        thw, cw, Fw = _arrays(simulate_emb("worn", seed=seed + 50, duration_s=20.0))
        worn = simulate_emb("worn", seed=seed + 60, duration_s=30.0)
        thv, cv, _ = _arrays(worn)
        e_stale = estimate(trained, thv, cv, TS)
        stale = rmse(e_stale.kf, _truth(worn))
        fresh = rmse(
            estimate(train(thw, cw, Fw, TS, structure=trained), thv, cv, TS).kf, _truth(worn)
        )
        # the stale models' fixed filter is over-confident on worn pads (mean NIS ~60), so
        # the session reports the adaptive-stiffness filter: below both of its inputs (the
        # noise-matched filter stayed above the torque balance), re-training still halves it
        assert e_stale.kf_switched
        assert stale < min(rmse(e_stale.torque_balance, _truth(worn)),
                           rmse(e_stale.stiffness, _truth(worn)))
        assert fresh < 0.6 * stale
        # its innovations show more than its noise admits: the band widens by the noise
        # scale, the estimate is the adaptive filter's to the bit, the truth mostly inside
        assert e_stale.kf_consistency["state"] == "over-confident"
        assert e_stale.kf_noise_scale == pytest.approx(e_stale.kf_consistency["mean_nis"])
        np.testing.assert_array_equal(e_stale.kf, e_stale.adaptive)
        np.testing.assert_allclose(
            e_stale.kf_std, e_stale.adaptive_std * np.sqrt(e_stale.kf_noise_scale))
        inside = np.abs(e_stale.kf - _truth(worn)) <= 1.96 * e_stale.kf_std
        assert inside.mean() > 0.8
        ratios.append(fresh / kf)
    assert np.mean(ratios) <= 1.3
    assert max(ratios) <= 1.45
    # heating pads: the fixed filter is over-confident there, the reported one switches to
    # the adaptive-stiffness filter, below its best input (the fixed one was 2.3x the torque
    # balance)
    hot = simulate_emb("heating", seed=6171, duration_s=40.0)
    th_h, c_h, _ = _arrays(hot)
    eh = estimate(trained, th_h, c_h, TS)
    truth_h = _truth(hot)
    assert eh.kf_switched and eh.kf_paper_nis > 1.5
    best = min(rmse(eh.stiffness, truth_h), rmse(eh.torque_balance, truth_h))
    assert rmse(eh.kf, truth_h) < best
    assert rmse(eh.kf, truth_h) < 0.8 * rmse(eh.kf_paper, truth_h)
    assert rmse(eh.adaptive, truth_h) < 1.3 * kf


def test_cli_outputs_and_json(tmp_path: Path) -> None:
    tr, _ = write_emb_simulation(
        simulate_emb("nominal", seed=6201, duration_s=15), tmp_path / "t.mcap"
    )
    ev, _ = write_emb_simulation(
        simulate_emb("nominal", seed=6202, duration_s=10), tmp_path / "e.parquet"
    )
    rt, _ = write_emb_simulation(simulate_emb("worn", seed=6203, duration_s=10), tmp_path / "w.csv")
    res = CliRunner().invoke(
        app,
        [
            "clamp-force",
            str(ev),
            "--train",
            str(tr),
            "--retrain",
            str(rt),
            "--out",
            str(tmp_path / "o"),
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    summ = json.loads(res.output)
    assert set(summ["rmse_kn"]) == {"kf", "ml_fusion", "stiffness", "torque_balance"}
    assert all(v > 0 for v in summ["rmse_kn"].values())
    assert "wear" in summ
    import pyarrow.parquet as pq

    tab = pq.read_table(tmp_path / "o" / "e" / "clamp_force.parquet")
    for col in ("time", "kf", "kf_std", "ml_fusion", "stiffness", "torque_balance",
                "kf_not_retrained"):
        assert col in tab.column_names
    # --retrain says the pads changed: the reported estimate is the re-trained models'
    # (it was computed and then only kept in a side column)
    kf, before = tab.column("kf").to_numpy(), tab.column("kf_not_retrained").to_numpy()
    assert not np.allclose(kf, before)  # two estimates, the re-trained one reported
    assert summ["rmse_kn"]["kf"] != summ["wear"]["rmse_kn_not_retrained"]["kf"]
    assert not any("gained less than" in w for w in summ["warnings"])  # worn pads: it did
    # a re-training session of the trained pads gains nothing, and that is said
    same = CliRunner().invoke(app, ["clamp-force", str(ev), "--train", str(tr), "--retrain",
                                    str(tr), "--out", str(tmp_path / "o2"), "--json"])
    assert same.exit_code == 0, same.output
    assert any("gained less than 5 %" in w for w in json.loads(same.output)["warnings"])
    assert (tmp_path / "o" / "e" / "index.html").stat().st_size > 0
    on_disk = json.loads((tmp_path / "o" / "e" / "summary.json").read_text())
    assert on_disk["training_session"] == str(tr)
    assert {"dynamic_stiffness", "torque_balance_per_amp"} <= set(on_disk["fitted"])
    ns, _ = write_emb_simulation(
        simulate_emb("nominal", seed=6204, duration_s=3, with_sensor=False), tmp_path / "n.mcap"
    )
    res = CliRunner().invoke(
        app, ["clamp-force", str(ns), "--train", str(tr), "--out", str(tmp_path / "o"), "--json"]
    )
    assert res.exit_code == 0, res.output
    assert set(json.loads(res.output)["rmse_kn"].values()) == {None}  # no sensor: no RMSE
    table = CliRunner().invoke(app, ["clamp-force", str(ns), "--train", str(tr), "--out",
                                     str(tmp_path / "o")], env={"COLUMNS": "120"})
    assert table.exit_code == 0, table.output
    assert re.search(r"(KF|reported) 95 % band: ± ", table.output), table.output
    assert "no usable clamp-force sensor" in table.output


def test_peak_is_a_force_held_not_a_one_sample_spike() -> None:
    from brakethermo.pipelines.clamp_force import held_peak

    v = 30e3 * np.sin(np.linspace(0.0, np.pi, 1001))
    for width in (1, 2, 3):  # the torque balance's inertia term at a current step
        spiky = v.copy()
        spiky[400:400 + width] = 40e3
        assert held_peak(spiky, 1e-3) == pytest.approx(30e3, rel=1e-4), width
    assert held_peak(v[:2], 1e-3) == 30e3 * np.sin(np.pi / 1000)


def _run_bad(tmp_path: Path, *args: str) -> str:
    res = CliRunner().invoke(app, ["clamp-force", *args, "--out", str(tmp_path / "o")])
    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output
    return res.output


def test_bad_inputs_exit_1(tmp_path: Path) -> None:
    sim = simulate_emb("nominal", seed=6301, duration_s=3)
    good, _ = write_emb_simulation(sim, tmp_path / "good.mcap")
    nosensor, _ = write_emb_simulation(
        simulate_emb("nominal", seed=6302, duration_s=3, with_sensor=False), tmp_path / "ns.mcap"
    )
    assert "sensor" in _run_bad(tmp_path, str(good), "--train", str(nosensor))
    walk = CliRunner().invoke(app, ["clamp-force", str(good), "--train", str(good),
                                    "--factor-walk", "1e6", "--out", str(tmp_path / "o")])
    assert walk.exit_code == 2 and "--factor-walk" in walk.output  # a usage error
    ch = {c.name: c for c in sim.session.channels}
    no_current = write_session(
        tmp_path / "nc.csv", SessionData((ch["motor_angle"], ch["clamp_force"]), {})
    )
    assert "motor_current" in _run_bad(tmp_path, str(no_current), "--train", str(good))
    short = write_emb_simulation(simulate_emb("nominal", seed=6303, duration_s=1),
                                 tmp_path / "short.mcap")[0]
    assert "at least 2.5 s" in _run_bad(tmp_path, str(good), "--train", str(short))
    still = write_session(
        tmp_path / "still.csv",
        SessionData(
            (
                Channel(
                    "motor_angle",
                    "rad",
                    ch["motor_angle"].time,
                    np.full(ch["motor_angle"].time.size, 2.0),
                ),
                ch["motor_current"],
                ch["clamp_force"],
            ),
            {},
        ),
    )
    assert "no braking" in _run_bad(tmp_path, str(still), "--train", str(good))
    odd = write_session(
        tmp_path / "odd.csv",
        SessionData(
            (
                Channel("motor_angle", "wibble", ch["motor_angle"].time, ch["motor_angle"].value),
                ch["motor_current"],
            ),
            {},
        ),
    )
    assert "unknown unit" in _run_bad(tmp_path, str(odd), "--train", str(good))


@settings(max_examples=30, deadline=None)
@given(
    a=st.floats(-1e4, 1e4), gap=st.floats(1.0, 1e4), sd=st.floats(1.0, 1e3), stb=st.floats(1.0, 1e3)
)
def test_ml_fusion_lies_between_and_favours_the_better_model(
    a: float, gap: float, sd: float, stb: float
) -> None:
    b = a + gap
    w = (ml_fusion(np.array([a]), np.array([b]), sd, stb)[0] - a) / gap  # weight on F_tb
    assert -1e-9 <= w <= 1.0 + 1e-9
    assert w == pytest.approx(sd**2 / (sd**2 + stb**2), abs=1e-9)


def test_heldout_check_chooses_the_gain_and_falls_back_to_the_best_estimate() -> None:
    """A caliper with four times the trained model's hysteresis: the stiffness model's
    errors are not white, and the paper's Q (its training RMSE squared) weighs it too
    much. The held-out halves of the training session choose a smaller Q, which beats the
    paper's filter and the ML fusion on an unseen session of that caliper; a check whose
    fusion did worse than the ML fusion reports the ML fusion with its held-out band."""
    cal = EmbCaliper(hysteresis=0.12, omega_h=0.5)
    th, cur, F = _arrays(simulate_emb("nominal", seed=6401, duration_s=40.0, caliper=cal))
    models = train(th, cur, F, TS)
    check = fusion_check(th, cur, F, TS)
    assert check is not None and set(check.rmse_by_q) == set(Q_SCALES)
    assert check.q_scale < 1.0
    assert check.rmse_by_q[check.q_scale] < 0.95 * check.rmse_by_q[1.0]
    ev = simulate_emb("nominal", seed=6402, duration_s=30.0, caliper=cal)
    th2, cur2, _ = _arrays(ev)
    truth = _truth(ev)
    chosen = estimate(models, th2, cur2, TS, check=check)
    paper = estimate(models, th2, cur2, TS, q_scale=1.0)
    assert chosen.kf_source == "kf"
    assert rmse(chosen.kf, truth) < 0.95 * min(rmse(paper.kf, truth),
                                               rmse(chosen.ml_fusion, truth))
    assert np.mean(np.abs(chosen.kf - truth) <= 1.96 * chosen.kf_std) > 0.85
    worse = replace(check, fusion_holds=False, best_single="ml_fusion",
                    coloured=replace(check.coloured, holds=False))
    fell = estimate(models, th2, cur2, TS, check=worse)
    assert fell.kf_source == "ml_fusion"
    np.testing.assert_array_equal(fell.kf, fell.ml_fusion)
    np.testing.assert_array_equal(fell.kf_std, check.rmse_n["ml_fusion"])


def test_simulate_rig_emb_writes_a_readable_session(tmp_path: Path) -> None:
    from brakethermo.io.load import load_session

    out = tmp_path / "e.mcap"
    args = ["simulate", "--rig", "emb", "--set", "duration_s=2", "--set", "scenario=heating"]
    res = CliRunner().invoke(app, [*args, "--set", "sensor=false", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["config"]["scenario"] == "heating"
    s = load_session(out, rate_hz=None, channels=("motor_angle", "motor_current", "clamp_force"))
    assert s.rate_hz == pytest.approx(1000.0) and not s.has("clamp_force")
    assert (tmp_path / "e.truth.parquet").exists()
    bad = CliRunner().invoke(
        app, ["simulate", "--rig", "emb", "--set", "scenario=rusty", "--out", str(out)]
    )
    assert bad.exit_code == 2 and "scenario='rusty'" in bad.output
    assert "Traceback" not in bad.output
    slow = CliRunner().invoke(app, ["simulate", "--rig", "emb", "--set", "force_lag_s=0.5",
                                    "--out", str(out)])
    assert slow.exit_code == 2 and "force_lag_s=0.5 out of range" in slow.output


@pytest.mark.parametrize("lag_s", [0.0, 0.008])
def test_simulate_rig_emb_sets_the_force_sensor_lag(tmp_path: Path, lag_s: float) -> None:
    """``--set force_lag_s=`` gives the logged clamp-force sensor that time constant (0: an
    ideal sensor): the sensor lags the true force by it (the shift that best aligns them,
    to a sample)."""
    out = tmp_path / "e.mcap"
    res = CliRunner().invoke(app, ["simulate", "--rig", "emb", "--set", "duration_s=6",
                                   "--set", f"force_lag_s={lag_s}", "--out", str(out)])
    assert res.exit_code == 0, res.output
    d = cfp.load_emb(out, need_sensor=True, role="training")
    truth = pd.read_parquet(tmp_path / "e.truth.parquet")["clamp_force"].to_numpy() * 1e3
    shifts = np.arange(0, 20)
    err = [rmse(d.force[k:], truth[:truth.size - k]) for k in shifts]
    a = np.exp(-TS / lag_s) if lag_s else 0.0
    assert abs(shifts[int(np.argmin(err))] - a / (1.0 - a)) <= 1.0  # the discrete lag's delay


def test_a_session_logged_at_another_rate_runs_on_the_coarser_grid(tmp_path: Path) -> None:
    """An independent caliper logged at 500 Hz against a 1 kHz training session was
    refused (CHANNELS.md: other rates are tolerated), and diagnose advised the very
    --retrain that failed so. Now every session runs on the coarsest rate, with a note,
    and the estimate is as good as at the training rate."""
    train = write_emb_simulation(simulate_emb("nominal", seed=6315, duration_s=20),
                                 tmp_path / "tr.mcap")[0]
    scores = {}
    for hz in (1000.0, 500.0):
        run = write_emb_simulation(simulate_emb("nominal", seed=6316, duration_s=10,
                                                caliper=replace(EmbCaliper(), rate_hz=hz)),
                                   tmp_path / f"s{hz:.0f}.mcap")[0]
        res = CliRunner().invoke(app, ["clamp-force", str(run), "--train", str(train),
                                       "--out", str(tmp_path / "o"), "--json"])
        assert res.exit_code == 0, res.output
        s = json.loads(res.stdout)
        scores[hz] = s["rmse_kn"]["kf"]
        said = " ".join(s["warnings"])
        assert ("tr.mcap: logged at 1000 Hz, run at 500 Hz" in said) == (hz == 500)
        assert s["rate_hz"] == pytest.approx(500.0 if hz == 500 else 1000.0)
    assert scores[500.0] < 1.5 * scores[1000.0] + 0.05
    # with --retrain the re-training session's note reaches the summary too
    res = CliRunner().invoke(app, ["clamp-force", str(run), "--train", str(train), "--retrain",
                                   str(train), "--out", str(tmp_path / "r"), "--json"])
    assert res.exit_code == 0, res.output
    said = json.loads(res.stdout)["warnings"]
    assert sum("tr.mcap: logged at 1000 Hz, run at 500 Hz" in w for w in said) == 2


def test_a_training_sensor_lagging_100_ms_is_found(tmp_path: Path) -> None:
    """The simulator's sensor lags up to 0.1 s; the candidates stopped at 20 ms, and a
    caliper trained on a 100 ms sensor was estimated 4.4 kN from the truth (band covering
    28 %): the lag is found and the estimate is near the truth."""
    sim = simulate_emb("nominal", seed=6313, duration_s=24,
                       caliper=replace(EmbCaliper(), force_lag_s=0.1))
    train = write_emb_simulation(sim, tmp_path / "tr.mcap")[0]
    run = write_emb_simulation(simulate_emb("nominal", seed=6314, duration_s=12,
                                            with_sensor=False), tmp_path / "run.mcap")
    res = cfp.clamp_force(run[0], train)
    assert res.train_lag is not None and res.train_lag.lag_s == pytest.approx(0.1, rel=0.5)
    truth = pd.read_parquet(run[1])["clamp_force"].to_numpy() * 1e3
    assert rmse(res.est.kf, truth) < 600.0  # N; 4400 when the lag was left in


@pytest.mark.parametrize("which", ["estimated", "training"])
def test_motor_angle_in_degrees_labelled_rad_is_refused(tmp_path: Path, which: str) -> None:
    """One file's angle in degrees labelled rad: 57x the other's spread. Both files are
    named (the estimate was 329 000 kN with no warning; a wrong training file blamed the
    other for a reversed sign)."""
    good = write_emb_simulation(simulate_emb("nominal", seed=6311, duration_s=3),
                                tmp_path / "good.mcap")[0]
    sim = simulate_emb("nominal", seed=6312, duration_s=3)
    ch = {c.name: c for c in sim.session.channels}
    deg = replace(ch["motor_angle"], value=np.degrees(ch["motor_angle"].value))
    bad = write_session(tmp_path / "deg.csv", SessionData(
        (deg, ch["motor_current"], ch["clamp_force"]), {}))
    args = (str(bad), "--train", str(good)) if which == "estimated" else (
        str(good), "--train", str(bad))
    said = _run_bad(tmp_path, *args)
    assert "'motor_angle'" in said and "x apart" in said and "deg read as rad" in said
    assert "good.mcap" in said or "deg.csv" in said


def test_a_gap_in_the_scoring_sensor_is_scored_around_and_said(tmp_path: Path) -> None:
    """One gap in the estimated session's force sensor: the RMSEs are taken on the rest
    and the gap is said on the console (the sensor was dropped without a word)."""
    good = write_emb_simulation(simulate_emb("nominal", seed=6321, duration_s=3),
                                tmp_path / "good.mcap")[0]
    sim = simulate_emb("nominal", seed=6322, duration_s=4)
    ch = {c.name: c for c in sim.session.channels}
    keep = (ch["clamp_force"].time < 1.0) | (ch["clamp_force"].time > 2.5)
    gap = replace(ch["clamp_force"], time=ch["clamp_force"].time[keep],
                  value=ch["clamp_force"].value[keep])
    gapped = write_session(tmp_path / "gap.csv", SessionData(
        (ch["motor_angle"], ch["motor_current"], gap), {}))
    res = CliRunner().invoke(app, ["clamp-force", str(gapped), "--train", str(good),
                                   "--out", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    assert "gap" in res.output and "warning" in res.output
    summ = json.loads(next((tmp_path / "o").rglob("summary.json")).read_text())
    assert summ["has_sensor"] and summ["rmse_kn"]["kf"] < 1.0


@given(lag_ms=st.floats(1.0, 15.0))
@settings(max_examples=15, deadline=None)
def test_advancing_a_first_order_sensor_undoes_its_delay_on_a_slow_force(lag_ms: float) -> None:
    """A first-order sensor of time constant τ reads a ramp τ late (after its transient);
    with its lag taken out (F + τ dF/dt) it reads the ramp itself, to rounding."""
    tau = lag_ms * 1e-3
    t = np.arange(4000) * TS
    F = 2000.0 + 8000.0 * t
    a = np.exp(-TS / tau)
    lagged = np.empty_like(F)
    lagged[0] = F[0]
    for k in range(1, F.size):
        lagged[k] = a * lagged[k - 1] + (1.0 - a) * F[k]
    settled = (t > 10 * tau) & (t < t[-1] - 2 * tau)
    # the discrete lag's exact delay on a ramp: a/(1-a) steps
    delagged = sensor_delagged(lagged, a / (1.0 - a) * TS, TS)
    assert np.max(np.abs(delagged - F)[settled]) < 1e-6 * F.max()
    assert np.max(np.abs(lagged - F)[settled]) > 0.5 * 8000.0 * tau
    np.testing.assert_array_equal(sensor_delagged(lagged, 0.0, TS), lagged)


def _written(tmp_path: Path, name: str, seed: int, cal: EmbCaliper, duration_s: float = 30.0
             ) -> tuple[Path, np.ndarray]:
    sim = simulate_emb("nominal", seed=seed, duration_s=duration_s, caliper=cal)
    path, _ = write_emb_simulation(sim, tmp_path / f"{name}.mcap")
    return path, _truth(sim)


def test_a_lagging_training_sensor_is_found_and_taken_out(tmp_path: Path) -> None:
    """Trained on a caliper whose force sensor lags 5 ms: the lag is found from the motor
    current (which answers the load at once), the models are fitted to the de-lagged
    sensor, and on an unseen session the filter is nearer the true force, with a band
    that covers it, than when it is trained on the lagging sensor as it reads; the
    session's own sensor, de-lagged by its own lag, is what its RMSE is against."""
    cal = EmbCaliper(force_lag_s=0.005)
    train_path, _ = _written(tmp_path, "train", 6411, cal, 60.0)
    eval_path, truth = _written(tmp_path, "eval", 6412, cal)
    res = cfp.clamp_force(eval_path, train_path)
    assert res.train_lag is not None and res.train_lag.lag_s == pytest.approx(0.005)
    assert res.models.sensor_lag_s == pytest.approx(0.005)
    assert res.scored_lag is not None and res.scored_lag.lag_s == pytest.approx(0.005)
    tr = cfp.load_emb(train_path, need_sensor=True, role="training")
    as_read = train(tr.theta, tr.current, tr.force, TS, sensor_lag_s=0.0)
    check_as_read = fusion_check(tr.theta, tr.current, tr.force, TS, sensor_lag_s=0.0)
    old = estimate(as_read, res.data.theta, res.data.current, TS, check=check_as_read)
    found = res.reported
    assert rmse(found.kf, truth) < 0.7 * rmse(old.kf, truth)
    assert np.mean(np.abs(found.kf - truth) <= 1.96 * found.kf_std) > 0.85
    # on the de-lagged sensor the stiffness is static (eq. 6's α0 at 0), the fixed filter
    # the ML fusion; the held-out halves chose the coloured-error smoother, below both
    # (and below the adaptive filter, which they preferred to the fixed one)
    assert res.check is not None and res.check.adaptive and found.kf_filter == "coloured"
    assert not found.kf_switched
    assert rmse(found.kf, truth) < 0.8 * min(rmse(found.ml_fusion, truth),
                                             rmse(found.adaptive, truth))
    summ = cfp.summary(res)
    assert summ["kf_noise"].startswith("the coloured-error smoother")
    assert "about 5 ms" in summ["sensor_lag"]["text"]
    frame = cfp.result_frame(res)
    np.testing.assert_allclose(frame["sensor_delagged"] * 1e3, scored_force(res))
    assert summ["rmse_kn"]["kf"] == pytest.approx(rmse(found.kf, scored_force(res)) / 1e3)


@pytest.mark.parametrize("viscous", [2.0e-4, 2.0e-3])
def test_speed_proportional_friction_is_no_sensor_lag(tmp_path: Path, viscous: float) -> None:
    """An ideal force sensor on a drive with ten times the viscous friction eq. 7 leaves
    out: de-lagging would add a term proportional to the motor speed, which the lag
    search's viscous column takes instead; the paper's ideal sensor is kept."""
    path, _ = _written(tmp_path, "ideal", 6413, EmbCaliper(force_lag_s=1e-5, viscous=viscous))
    d = cfp.load_emb(path, need_sensor=True, role="training")
    lag = cfp.choose_sensor_lag(d.theta, d.current, d.force, d.ts)
    assert lag is not None and lag.lag_s == 0.0


def test_stiffness_autoregression_stays_a_relaxation_on_a_static_force() -> None:
    """A de-lagged sensor follows the angle with no lag of its own, which leaves eq. 6's
    autoregression unidentified; the fit stays in the physical range 0 <= α0 < 1
    (unbounded it went to -0.97 on this session, a mode that flips sign every sample)."""
    cal = EmbCaliper(force_lag_s=0.005)
    th, _, F = _arrays(simulate_emb("nominal", seed=6411, duration_s=30.0, caliper=cal))
    F = sensor_delagged(F, 0.005, TS)
    ds = fit_dynamic_stiffness(th, F, TS)
    assert 0.0 <= ds.alpha0 < 1.0
    assert rmse(ds.simulate(th), F) < 1.2 * rmse(np.stack(
        [th**3, th**2, th, np.ones_like(th)], axis=1) @ np.linalg.lstsq(np.stack(
            [th**3, th**2, th, np.ones_like(th)], axis=1), F, rcond=None)[0], F)


def test_delagging_keeps_gaps_and_does_not_reach_across_them() -> None:
    """Each stretch between gaps is differentiated on its own: a gap stays a gap, the
    samples beside it are the stretch's own F + τ dF/dt (no interpolated fill leaks in),
    and a stretch shorter than the derivative window still gets a derivative."""
    t = np.arange(3000) * TS
    F = 1000.0 + 500.0 * np.sin(2 * np.pi * 2.0 * t)
    dF = 500.0 * 2 * np.pi * 2.0 * np.cos(2 * np.pi * 2.0 * t)
    lag = 0.004
    holed = F.copy()
    holed[1000:1200] = np.nan  # a 0.2 s dropout
    holed[2500] = np.nan  # one missing sample
    out = sensor_delagged(holed, lag, TS)
    assert np.isnan(out[1000:1200]).all() and np.isnan(out[2500])
    ok = np.isfinite(out)
    np.testing.assert_allclose(out[ok], (F + lag * dF)[ok], atol=0.05)
    short = sensor_delagged(F[:4], lag, TS)
    assert np.isfinite(short).all()


def test_eq7_choice_scores_around_a_gap_in_the_force_sensor() -> None:
    """A few NaN samples of the sensor (the training allows gaps) are scored around: the
    choice is the one without the gap, not the first pair by default (a NaN score)."""
    rng = np.random.default_rng(1)
    ts, K = 1e-3, 20000
    t = np.arange(K) * ts
    theta = 30.0 * np.sin(np.pi * t) + np.round(rng.normal(0.0, 1.0, K)) * 0.01
    tb = TorqueBalance(gamma=1e-3, inertia=1e-4, mu=1e-4, offset=0.2, bias=0.05,
                       omega_s=0.3)
    F = np.clip(2000.0 * (1.0 + np.sin(np.pi * t)), 0.0, None) + rng.normal(0.0, 20.0, K)
    omega, acc = motor_rates(theta, ts, 1)
    sgn = np.tanh(omega / 0.3)
    current = ((tb.gamma + tb.mu * sgn) * F + tb.inertia * acc + tb.offset * sgn + tb.bias
               + rng.normal(0.0, 0.02, K))
    whole = eq7_choice(theta, current, F, ts)
    F_gap = F.copy()
    F_gap[5000:5010] = np.nan
    assert eq7_choice(theta, current, F_gap, ts) == whole == (1, 0.2)


def test_short_training_noise_only_sensor_and_no_negative_force(tmp_path: Path) -> None:
    """An independent caliper's findings: a 3 s training left the fixed filter unchecked
    without a word; a training sensor reading only noise around zero was called "sign
    reversed"; estimates went down to -0.86 kN. Now a warning, the right cause, and every
    reported force >= 0."""
    from brakethermo.models.clamp_force import band_factor

    short = write_emb_simulation(simulate_emb("nominal", seed=6311, duration_s=3),
                                 tmp_path / "short.mcap")[0]
    val = write_emb_simulation(simulate_emb("nominal", seed=6312, duration_s=4),
                               tmp_path / "val.mcap")[0]
    res = cfp.clamp_force(val, short)
    summ = cfp.summary(res)
    assert summ["fusion_check"] is None
    assert any("too short to check the filter" in w for w in summ["warnings"]), summ["warnings"]
    frame = cfp.result_frame(res)
    assert (frame[["kf", "ml_fusion", "stiffness", "torque_balance"]] >= 0.0).all().all()
    from types import SimpleNamespace

    below = np.array([-860.0, 0.0, 1200.0])
    fake = SimpleNamespace(kf=below, kf_paper=below, ml_fusion=below, stiffness=below,
                           torque_balance=below, adaptive=below)
    for v in estimator_series(fake).values():  # type: ignore[arg-type]
        np.testing.assert_array_equal(v, [0.0, 0.0, 1200.0])
    sim = simulate_emb("nominal", seed=6313, duration_s=3)
    ch = {c.name: c for c in sim.session.channels}
    noise = np.random.default_rng(0).normal(0.0, 0.03, ch["clamp_force"].value.size)
    zero = write_session(tmp_path / "zero.csv", SessionData(
        (ch["motor_angle"], ch["motor_current"], replace(ch["clamp_force"], value=noise)), {}))
    said = _run_bad(tmp_path, str(val), "--train", str(zero))
    assert "noise around zero" in said and "reversed" not in said
    # the band factor: the mean of z^2, or what covers 95 % of heavy-tailed errors
    gauss = np.random.default_rng(1).normal(size=20000) ** 2
    assert band_factor(gauss) == pytest.approx(1.0, abs=0.05)
    rng = np.random.default_rng(2)  # quiet most of the time, 15 % of it 4x as loud
    mixed = (rng.normal(size=20000) * np.where(rng.random(20000) < 0.15, 2.2, 0.5)) ** 2
    assert np.mean(mixed) < 1.0 and np.mean(mixed <= 1.96**2) < 0.95
    assert band_factor(mixed) > 1.1 and np.mean(mixed / band_factor(mixed) <= 1.96**2) >= 0.949


def test_the_coloured_band_grows_with_the_force_rate_its_held_out_errors_show() -> None:
    """The band is at least the held-out error measured at the force's rate of change:
    on an independent caliper a constant band covered 60 % where the force moved fastest
    and 100 % where it stood (90 % overall; 96 % with this)."""
    from brakethermo.models.clamp_force import ColouredError, _rate_bins

    rng = np.random.default_rng(3)
    rate = np.abs(rng.standard_cauchy(40000)) * 5e3  # N/s
    e2 = (rng.normal(size=rate.size) * (150.0 + 0.01 * np.minimum(rate, 1e5))) ** 2
    knots, mse = _rate_bins(rate, e2)
    assert len(knots) == 8 and np.all(np.diff(knots) > 0) and np.all(np.diff(mse) >= 0)
    col = ColouredError(0.1, 0.03, 300.0, 150.0**2, 1.0, True, True, knots, mse)
    slow, fast = col.variance(1e-3, np.array([10.0, 1e5]))
    assert fast > 4 * slow and slow >= col.variance(1e-3) - 1e-9
    z2 = e2 / col.variance(1e-3, rate)
    assert 0.93 <= np.mean(z2 <= 1.96**2) <= 0.99
    assert _rate_bins(rate[:50], e2[:50]) == ((), ())


def test_the_coloured_band_also_holds_the_errors_its_held_out_halves_show_at_high_force(
) -> None:
    """An independent caliper's progressive stiffness: at steady holds above 20 kN the
    estimate erred 0.74 kN RMS (+0.43 kN) where a band by rate alone gave 0.27 kN (44 %
    covered there, 81.5 % of the applied samples). The band is at least the held-out error
    in bins of the estimated force too."""
    from brakethermo.models.clamp_force import ColouredError, _rate_bins

    rng = np.random.default_rng(5)
    force = rng.uniform(0.0, 30e3, 40000)  # N, steady (rate 0)
    e2 = (rng.normal(size=force.size) * (100.0 + 0.03 * force)) ** 2
    f_knots, f_mse = _rate_bins(force, e2)
    rate_only = ColouredError(0.1, 0.03, 300.0, 150.0**2, 1.0, True, True, (0.0, 1e5),
                              (150.0**2, 150.0**2))
    both = replace(rate_only, force_knots=f_knots, force_vars=f_mse)
    high = force > 20e3
    cover = {name: np.mean(e2[high] <= 1.96**2 * c.variance(1e-3, 0.0, force[high]))
             for name, c in (("rate", rate_only), ("both", both))}
    assert cover["rate"] < 0.5 and cover["both"] > 0.9
    assert both.variance(1e-3, 0.0, 1e3) == pytest.approx(rate_only.variance(1e-3, 0.0, 1e3),
                                                          rel=0.5)


def test_a_motor_side_change_is_not_blamed_on_the_pads_and_the_band_admits_it(
        tmp_path: Path) -> None:
    """An independent caliper whose winding ran hotter than in training (torque constant
    11 % lower): the adaptive filter followed the torque balance to 1.33 kN RMS against
    0.40 for the stiffness model, the page said the pads had changed and the band covered
    35 %. The pads and the motor side read alike here: the text and a warning say so, the
    band reaches past the stiffness model's estimate, and this session's own sensor shows
    the reported estimate worse than an input it fuses."""
    train = write_emb_simulation(simulate_emb("nominal", seed=931, duration_s=30),
                                 tmp_path / "tr.mcap")[0]
    hot, truth = write_emb_simulation(simulate_emb(
        "nominal", seed=932, duration_s=20, caliper=replace(EmbCaliper(), km=0.045)),
        tmp_path / "hot.mcap")
    res = cfp.clamp_force(hot, train)
    est, s = res.reported, cfp.summary(res)
    assert est.kf_filter == "adaptive" and est.motor_alike == pytest.approx(1.11, abs=0.03)
    assert "cannot tell apart" in s["kf_noise"] and "no longer holds" not in s["kf_noise"]
    # the text's factor is the median while applied, not the page's final one (new-user
    # test: "a stiffness factor 0.72" beside a card "final stiffness factor 0.766")
    assert (f"{s['stiffness_factor_applied_median']:.2f} (the stiffness factor's median"
            in s["kf_noise"]), s["kf_noise"]
    said = " ".join(s["warnings"])
    assert "disagree by a factor 1.1" in said and "worse than the dynamic-stiffness" in said
    F = pd.read_parquet(truth)["clamp_force"].to_numpy() * 1e3
    assert np.mean(np.abs(est.kf - F) <= 1.96 * est.kf_std) > 0.85  # 0.51 spanning kf_paper
    np.testing.assert_array_equal(est.adaptive_band, est.kf_std)  # kf_adaptive_std as kf's
    # worn pads (a 12 % stiffer, 1.2 rad later contact): a factor no motor moves, the pads'
    worn = write_emb_simulation(simulate_emb("worn", seed=933, duration_s=20),
                                tmp_path / "worn.mcap")[0]
    res = cfp.clamp_force(worn, train)
    est, s = res.reported, cfp.summary(res)
    assert est.kf_filter == "adaptive" and est.motor_alike is None
    assert "more than a motor's torque constant" in s["kf_noise"]
    assert (f"a stiffness factor {s['stiffness_factor_applied_median']:.2f}, its median"
            in s["kf_noise"]), s["kf_noise"]
    assert not any("disagree by a factor" in w for w in s["warnings"])
    assert np.all(est.adaptive_band >= est.adaptive_std)  # its band as published


def test_a_band_the_sessions_own_sensor_refutes_is_said(tmp_path: Path) -> None:
    """Scored against the session's own force sensor, a kf band covering too little of
    the applies is said (coverage_95_kf, a warning naming diagnose and --retrain): here a
    sensor reading 1.4x (a gain or unit fault: the caliper itself is the trained one); the
    same session with its sensor right says nothing. Our simulator's calipers stay inside
    the band even with four times the trained hysteresis (93 %); an independent one with
    three times it did not (63 % of its applied samples)."""
    tr, _ = write_emb_simulation(simulate_emb("nominal", seed=6501, duration_s=30.0),
                                 tmp_path / "tr.mcap")
    sim = simulate_emb("nominal", seed=6502, duration_s=20.0)
    right, _ = write_emb_simulation(sim, tmp_path / "right.mcap")
    channels = tuple(replace(c, value=1.4 * c.value) if c.name == "clamp_force" else c
                     for c in sim.session.channels)
    off = write_session(tmp_path / "off.mcap", SessionData(channels, sim.session.facts))
    quiet = cfp.summary(cfp.clamp_force(right, tr))
    assert quiet["coverage_95_kf"]["applied"] >= 0.8
    assert not any("kf's 95 % band covers" in w for w in quiet["warnings"])
    loud = cfp.summary(cfp.clamp_force(off, tr))
    assert loud["coverage_95_kf"]["applied"] < 0.8
    said = [w for w in loud["warnings"] if "kf's 95 % band covers" in w]
    assert said and "diagnose --rig emb" in said[0] and "--retrain" in said[0]


def test_a_session_too_short_for_its_sensors_lag_is_scored_against_its_sensor(
        tmp_path: Path) -> None:
    """A 2 s session logging clamp_force was said to have no sensor (has_sensor false,
    rmse_kn null, no word): its lag cannot be chosen on 2 s, and that set the sensor
    aside. It is scored against the sensor as logged, and the lag text says why."""
    train = write_emb_simulation(simulate_emb("nominal", seed=6331, duration_s=12),
                                 tmp_path / "train.mcap")[0]
    short = write_emb_simulation(simulate_emb("nominal", seed=6332, duration_s=2),
                                 tmp_path / "short.mcap")[0]
    summ = cfp.summary(cfp.clamp_force(short, train))
    assert summ["has_sensor"] is True
    assert 0.0 < summ["rmse_kn"]["kf"] < 1.0
    assert summ["sensor_lag"]["this_session"] is None
    assert "against its own sensor as logged" in summ["sensor_lag"]["text"]
    assert "too short to choose the sensor's lag" in summ["sensor_lag"]["text"]
