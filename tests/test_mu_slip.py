"""mu-slip: oracle tyre figures, the paper's EKF case, rig sessions of our simulator, the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from brakethermo.cli import app
from brakethermo.io.load import load_session
from brakethermo.io.writers import Channel, SessionData, write_session
from brakethermo.models.mu_slip import SPLINE, best_fit, fit_families, rudd_ekf
from brakethermo.pipelines.mu_slip import MuSlipOptions, mu_slip, summary
from brakethermo.rigs.tyre import (
    burckhardt_mu,
    burckhardt_peak,
    magic_formula_mu,
    magic_formula_peak,
    rudd_hessian,
    rudd_jacobian,
    rudd_mu,
)
from brakethermo.sim.tyre_rig import (
    TYRE_PRESETS,
    BrushTyre,
    simulate_tyre_rig,
    write_tyre_simulation,
)


def test_magic_formula_oracle() -> None:
    # MFeval PacejkaBook_Defaults: Fx0 = 4000 sin(1.6 atan(10 κ))
    fx = 4000.0 * magic_formula_mu(np.array([0.05, 0.10]), 10.0, 1.6, 1.0)
    np.testing.assert_allclose(fx, [2702.57, 3804.23], atol=0.005)
    mu, s = magic_formula_peak(10.0, 1.6, 1.0)
    assert 4000.0 * mu == pytest.approx(4000.0)
    assert s == pytest.approx(0.1497, abs=5e-5)


def test_burckhardt_oracle() -> None:
    mu, s = burckhardt_peak(1.2801, 23.99, 0.52)
    assert mu == pytest.approx(1.17, abs=0.005)
    assert s == pytest.approx(0.17, abs=0.005)
    grid = np.linspace(0, 1, 100001)
    assert burckhardt_mu(grid, 1.2801, 23.99, 0.52).max() == pytest.approx(mu, abs=1e-8)


def test_rudd_derivatives_match_finite_differences() -> None:
    s, m, p, e = 0.08, 0.4, 0.15, 1e-6
    J = rudd_jacobian(s, m, p)
    np.testing.assert_allclose(
        J,
        [
            (rudd_mu(s, m + e, p) - rudd_mu(s, m - e, p)) / (2 * e),
            (rudd_mu(s, m, p + e) - rudd_mu(s, m, p - e)) / (2 * e),
        ],
        rtol=1e-6,
    )
    h_mm, h_ss, h_ms = rudd_hessian(s, m, p)
    d_sp = lambda pp: rudd_jacobian(s, m, pp)  # noqa: E731
    np.testing.assert_allclose(h_ss, (d_sp(p + e)[1] - d_sp(p - e)[1]) / (2 * e), rtol=1e-5)
    np.testing.assert_allclose(h_ms, (d_sp(p + e)[0] - d_sp(p - e)[0]) / (2 * e), rtol=1e-5)
    assert h_mm == 0.0


def test_paper_case_ekf_within_one_sigma() -> None:
    """μp 0.35, sp 0.15, σ 0.04, 40 points, square-biased slips; seeds never looked at."""
    inside = 0
    seeds = range(7000, 7020)
    for seed in seeds:
        rng = np.random.default_rng(seed)
        s = (np.arange(1, 41) / 40.0) ** 2
        mu = rudd_mu(s, 0.35, 0.15) + rng.normal(0.0, 0.04, 40)
        r = rudd_ekf(s, mu, 0.04, np.array([0.6, 0.2]), np.diag([0.5**2, 0.1**2]))
        err = np.abs(r.x_filt[-1] - [0.35, 0.15]) / np.sqrt(r.var_filt[-1])
        inside += bool((err < 1.0).all())
    assert inside >= 0.9 * len(seeds)


@pytest.mark.parametrize(
    ("tyre", "seed", "ext"),
    [
        ("dry", 8101, "mcap"),
        ("wet", 8103, "csv"),
        ("wet", 8104, "parquet"),
    ],
)
def test_rig_sessions_peak_targets(tmp_path: Path, tyre: str, seed: int, ext: str) -> None:
    sim = simulate_tyre_rig(tyre, seed=seed)
    path, _ = write_tyre_simulation(sim, tmp_path / f"rig.{ext}")
    radius = 0.3 if ext == "csv" else None  # CSV carries no session facts
    summ = summary(mu_slip(path, MuSlipOptions(radius_m=radius)))
    mu_true, s_true = sim.peak
    assert abs(summ["peak"]["mu"] / mu_true - 1.0) < 0.05
    # The truth is a brush tyre, outside every fitted family: its peak is sharper and
    # earlier than the families' smooth ones, which put it 0.02-0.03 to the right; the
    # smoothing spline, of no shape, wins held-out and puts it where the points have it
    fams = {f["model"]: f for f in summ["families"]}
    assert fams["magic-formula"]["slip_peak"] - s_true > 0.015
    assert summ["peak"]["model"] == SPLINE
    assert abs(summ["peak"]["slip"] - s_true) < 0.012
    # the two-parameter curve overshoots and says so
    assert summ["shape_mismatch"]["rudd_mu_peak_minus_best_pct"] > 5.0
    # the reported peak's band admits the curve's form: it holds the brush's peak, and is
    # never narrower than the EKF's own
    peak = summ["peak"]
    assert abs(peak["mu"] - mu_true) <= 1.96 * peak["mu_std"]
    assert abs(peak["slip"] - s_true) <= 1.96 * peak["slip_std"]
    assert peak["mu_std"] >= summ["ekf"]["mu_peak_std"] and len(peak["families"]) >= 1


def test_a_force_that_drops_out_is_left_out_or_refused(tmp_path: Path) -> None:
    """The drag force at 0 for 0.2 s inside the ramp put the peak at 0.76 against 1.16,
    with a tight band and no word; frozen over much of the ramp, the curve is not there."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from brakethermo.errors import DataError

    sim = simulate_tyre_rig("dry", seed=8105)
    path, _ = write_tyre_simulation(sim, tmp_path / "rig.parquet")
    table = pq.read_table(path)
    frame = table.to_pandas()
    t = frame["time"].to_numpy()
    a, b = int(0.35 * len(t)), int(0.6 * len(t))  # the ramp's middle

    def broken(name: str, sl: slice, value: float) -> Path:
        f = frame.copy()
        f.loc[f.index[sl], "drag_force"] = value
        out = tmp_path / f"{name}.parquet"
        pq.write_table(pa.Table.from_pandas(f, schema=table.schema, preserve_index=False), out)
        return out

    mid = (a + b) // 2
    drop = broken("drop", slice(mid, mid + max(int(0.2 / (t[1] - t[0])), 101)), 0.0)
    summ = summary(mu_slip(drop, MuSlipOptions()))
    assert abs(summ["peak"]["mu"] / sim.peak[0] - 1.0) < 0.05
    assert any("'drag_force' holds one value exactly" in w and "left out" in w
               for w in summ["warnings"])
    stuck = broken("stuck", slice(a, b), float(frame["drag_force"].iloc[a]))
    with pytest.raises(DataError, match="froze or dropped out"):
        mu_slip(stuck, MuSlipOptions())


def test_a_second_ramp_in_the_log_is_said(tmp_path: Path) -> None:
    """A dry then a wet ramp in one log: only the first was reported, without a word."""
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    path, _ = write_tyre_simulation(simulate_tyre_rig("dry", seed=8107), tmp_path / "a.parquet")
    table = pq.read_table(path)
    one = table.to_pandas()
    two = one.copy()
    two["time"] = two["time"] + one["time"].iloc[-1] + (one["time"].iloc[1] - one["time"].iloc[0])
    both = tmp_path / "two.parquet"
    pq.write_table(pa.Table.from_pandas(pd.concat([one, two], ignore_index=True),
                                        schema=table.schema, preserve_index=False), both)
    said = summary(mu_slip(both, MuSlipOptions()))["warnings"]
    assert any("another braking ramp" in w for w in said), said
    assert not any("another braking ramp" in w
                   for w in summary(mu_slip(path, MuSlipOptions()))["warnings"])


def test_a_wheel_let_go_from_lock_swings_without_braking_again() -> None:
    """An independent rig's wheel, released from lock, swung to slip -0.73 and back to
    +0.45 within 60 ms before it rolled free: no second ramp; a real one after free
    rolling still is."""
    from types import SimpleNamespace

    from brakethermo.pipelines.mu_slip import later_ramp_s

    dt = 0.002
    t = np.arange(0.0, 4.0, dt)
    slip = np.where(t < 1.0, 1.0, 0.0)  # locked, then let go at 1 s
    swing = (t >= 1.0) & (t < 1.1)
    slip[swing] = 0.8 * np.exp(-(t[swing] - 1.0) / 0.03) * np.sin(2 * np.pi * 12 * (t[swing] - 1.0))
    session = SimpleNamespace(time=t, dt=dt)
    assert later_ramp_s(session, slip, int(0.99 / dt)) is None
    again = slip.copy()
    again[t >= 2.5] = np.minimum(1.0, (t[t >= 2.5] - 2.5) * 2.0)  # braking again at 2.5 s
    assert later_ramp_s(session, again, int(0.99 / dt)) == pytest.approx(2.55, abs=0.01)


def test_cli_writes_all_outputs(tmp_path: Path) -> None:
    path, _ = write_tyre_simulation(
        simulate_tyre_rig("dry", seed=8102), tmp_path / "rig.mcap"
    )
    res = CliRunner().invoke(app, ["mu-slip", str(path), "--out", str(tmp_path / "o"), "--json"])
    assert res.exit_code == 0, res.output
    summ = json.loads(res.output)
    assert {"ekf", "lm_one_pass", "lm_converged", "peak", "shape_mismatch"} <= set(summ)
    for key in ("ekf", "lm_one_pass", "lm_converged"):  # OUTPUTS.md "mu-slip"
        assert {"mu_peak", "slip_peak"} <= set(summ[key])
    assert {"mu", "slip", "model"} <= set(summ["peak"])
    assert "two-parameter" in summ["shape_mismatch"]["words"]
    folder = tmp_path / "o" / "rig"
    on_disk = json.loads((folder / "summary.json").read_text())
    assert on_disk["peak"] == summ["peak"]
    import pyarrow.parquet as pq

    cols = pq.read_table(folder / "mu_slip.parquet").column_names
    for col in ("time", "slip", "mu", "ekf_mu_peak", "ekf_slip_peak"):
        assert col in cols and (col in ("time", "slip", "mu") or f"{col}_std" in cols)
    for name in (
        "mu_slip.parquet",
        "summary.json",
        "index.html",
        "ekf_animation.gif",
        "ekf_convergence.png",
        "curve_fits.png",
    ):
        assert (folder / name).stat().st_size > 0


def test_impossible_answers_are_said_or_refused(tmp_path: Path) -> None:
    """A radius 33 % off gave a peak μ of -16 with exit 0; an EKF started far from the
    tyre (--mu-max 0.11) ended at μ -0.89 without a word: the free-rolling slip refuses
    the first (naming the radius the speeds give), the summary's warnings say the second,
    and a clean run has none."""
    path, _ = write_tyre_simulation(simulate_tyre_rig("dry", seed=8107), tmp_path / "r.mcap")
    clean = summary(mu_slip(path))
    assert clean["warnings"] == []
    far = summary(mu_slip(path, MuSlipOptions(mu_range=(0.1, 0.11))))
    assert any("expected range" in w for w in far["warnings"]), far["warnings"]
    assert 0.0 < far["peak"]["slip_std"] < 1.0
    res = CliRunner().invoke(app, ["mu-slip", str(path), "--radius", "0.4",
                                   "--out", str(tmp_path / "o")])
    assert res.exit_code == 1 and "free rolling" in res.output and "0.300 m" in res.output, (
        res.output)
    bad = CliRunner().invoke(app, ["mu-slip", str(path), "--mu-max", "0",
                                   "--out", str(tmp_path / "o")])
    assert bad.exit_code == 2 and "--mu-max 0" in bad.output  # a usage error
    # a log that starts already braking has no free rolling to judge: the right peak, no
    # word about the radius (the first version of the check refused it)
    sim = simulate_tyre_rig("dry", seed=8107)
    ch = {c.name: c for c in sim.session.channels}
    v, w = ch["vehicle_speed"], ch["wheel_speed"]
    slip = 1.0 - np.interp(v.time, w.time, w.value) * 0.3 / np.maximum(v.value, 1.0)
    t0 = float(v.time[np.flatnonzero(slip > 0.08)[0]])
    cut = tuple(Channel(c.name, c.unit, c.time[c.time >= t0] - t0, c.value[c.time >= t0])
                for c in sim.session.channels)
    late = write_session(tmp_path / "late.parquet", SessionData(cut, sim.session.facts))
    summ = summary(mu_slip(late))
    assert summ["warnings"] == [] and abs(summ["peak"]["mu"] - clean["peak"]["mu"]) < 0.05


@pytest.mark.parametrize("radius", ["0.9", "0.1"])
def test_a_given_radius_far_off_is_named_before_the_units(tmp_path: Path, radius: str) -> None:
    """--radius 0.9 (or 0.1) on a 0.300 m wheel ended "vehicle_speed looks like m/s
    labelled km/h: set its unit to m/s" though the channel is right and the radius was
    typed by the user (new-user test): the given radius is named first, with the radius
    the free-rolling speeds give."""
    path, _ = write_tyre_simulation(simulate_tyre_rig("dry", seed=8107), tmp_path / "r.mcap")
    res = CliRunner().invoke(app, ["mu-slip", str(path), "--radius", radius,
                                   "--out", str(tmp_path / "o")])
    text = " ".join(res.output.split())
    assert res.exit_code == 1, text
    assert f"the given --radius {radius} m may be wrong" in text, text
    assert "give --radius 0.300" in text and "wheel_radius_m" in text, text
    assert text.index("the given --radius") < text.index("labelled"), text


def test_slip_ratio_channel_used(tmp_path: Path) -> None:
    sim = simulate_tyre_rig("wet", seed=8105, log_slip=True)
    chans = tuple(c for c in sim.session.channels if c.name != "wheel_speed")
    path = write_session(tmp_path / "s.parquet", SessionData(chans, {"rig": "tyre"}))
    assert summary(mu_slip(path))["wheel_radius_m"] is None
    said = summary(mu_slip(path, MuSlipOptions(radius_m=0.3)))["warnings"]
    assert any("--radius 0.3 m is not used" in w for w in said)  # was taken silently


def _bad(tmp_path: Path, channels: tuple[Channel, ...], facts: dict[str, str], *args: str) -> str:
    path = write_session(tmp_path / "bad.parquet", SessionData(channels, facts))
    res = CliRunner().invoke(app, ["mu-slip", str(path), "--out", str(tmp_path / "o"), *args])
    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output
    return res.output


def test_bad_inputs_exit_1(tmp_path: Path) -> None:
    sim = simulate_tyre_rig("dry", seed=8106)
    ch = {c.name: c for c in sim.session.channels}
    facts = dict(sim.session.facts)
    no_drag = tuple(c for n, c in ch.items() if n != "drag_force")
    assert "drag_force" in _bad(tmp_path, no_drag, facts)
    rolling = tuple(Channel(c.name, c.unit, c.time[:1500], c.value[:1500]) for c in ch.values())
    assert "no braking" in _bad(tmp_path, rolling, facts)
    no_radius = {k: v for k, v in facts.items() if k != "wheel_radius_m"}
    # without a radius, and no free rolling to take one from (μ 0.3 throughout): refused
    braked = tuple(Channel(c.name, c.unit, c.time, 0.3 * ch["normal_force"].value)
                   if c.name == "drag_force" else c for c in ch.values())
    assert "radius" in _bad(tmp_path, braked, no_radius)
    odd = tuple(
        Channel(c.name, "wibble/s" if c.name == "vehicle_speed" else c.unit, c.time, c.value)
        for c in ch.values()
    )
    assert "unknown unit" in _bad(tmp_path, odd, facts)


@settings(max_examples=40, deadline=None)
@given(
    c1=st.floats(0.3, 2.0),
    c2=st.floats(5.0, 60.0),
    c3=st.floats(0.05, 0.8),
)
def test_burckhardt_peak_is_the_maximum(c1: float, c2: float, c3: float) -> None:
    mu, _ = burckhardt_peak(c1, c2, c3)
    grid = np.linspace(0.0, 1.0, 20001)
    assert mu == pytest.approx(burckhardt_mu(grid, c1, c2, c3).max(), abs=1e-6)


@settings(max_examples=40, deadline=None)
@given(
    B=st.floats(3.0, 40.0), C=st.floats(1.05, 1.95), D=st.floats(0.2, 1.5), E=st.floats(-1.0, 0.9)
)
def test_magic_formula_peak_is_the_maximum(B: float, C: float, D: float, E: float) -> None:
    mu, s = magic_formula_peak(B, C, D, E)
    grid = np.linspace(0.0, max(1.0, 2 * s), 40001)
    assert mu == pytest.approx(magic_formula_mu(grid, B, C, D, E).max(), abs=1e-6)
    assert magic_formula_mu(s, B, C, D, E) == pytest.approx(mu, abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(mu_p=st.floats(0.05, 2.0), s_p=st.floats(0.02, 0.5))
def test_rudd_curve_peaks_at_its_parameters(mu_p: float, s_p: float) -> None:
    assert rudd_mu(s_p, mu_p, s_p) == pytest.approx(mu_p)
    grid = np.linspace(0.0, 1.0, 20001)
    assert rudd_mu(grid, mu_p, s_p).max() <= mu_p * (1 + 1e-12)


def test_simulate_rig_tyre_writes_a_readable_session_and_its_true_peak(tmp_path: Path) -> None:
    out = tmp_path / "t.parquet"
    args = ["simulate", "--rig", "tyre", "--set", "tyre=low-mu", "--set", "log_slip=true"]
    res = CliRunner().invoke(app, [*args, "--seed", "3", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    info = json.loads(res.output)
    assert info["rig"] == "tyre" and info["config"]["log_slip"] is True
    tyre = TYRE_PRESETS["low-mu"]
    grid = np.linspace(0.0, 1.0, 100001)
    mu = np.array([tyre.mu(s, 20.0, 4000.0) for s in grid])
    assert (info["peak_mu"], info["peak_slip"]) == pytest.approx(
        (mu.max(), grid[mu.argmax()]), abs=2e-5)
    assert (tmp_path / "t.truth.parquet").exists()
    s = load_session(out, rate_hz=None)
    assert s.has("slip_ratio") and s.has("drag_force")
    bad = CliRunner().invoke(
        app, ["simulate", "--rig", "tyre", "--set", "tyre=slick", "--out", str(out)]
    )
    assert bad.exit_code == 2 and "tyre='slick'" in bad.output
    assert "Traceback" not in bad.output


@settings(max_examples=25, deadline=None)
@given(
    mu_static=st.floats(0.2, 1.6),
    fall=st.floats(0.05, 0.6),
    v_stribeck=st.floats(0.5, 10.0),
    stiffness=st.floats(5.0, 40.0),
    speed=st.floats(3.0, 40.0),
)
def test_brush_truth_tyre_is_a_brush(mu_static: float, fall: float, v_stribeck: float,
                                     stiffness: float, speed: float) -> None:
    """Rolling gives no force, lock gives the sliding friction, the curve rises as
    3x - 3x^2 + x^3 of the brush at small slip, and the stated peak is its maximum."""
    tyre = BrushTyre(mu_static, mu_static * (1 - fall), v_stribeck, stiffness)
    assert tyre.mu(0.0, speed, 4000.0) == 0.0
    sliding = tyre.mu_sliding + (mu_static - tyre.mu_sliding) * np.exp(-speed / v_stribeck)
    assert tyre.mu(1.0, speed, 4000.0) == pytest.approx(sliding)
    s = 1e-5  # slope at the origin: the slip stiffness per load
    assert tyre.mu(s, speed, 4000.0) / s == pytest.approx(stiffness, rel=1e-3)
    mu_p, s_p = tyre.peak(speed, 4000.0)
    grid = np.linspace(0.0, 1.0, 20001)
    assert mu_p >= max(tyre.mu(x, speed, 4000.0) for x in grid) - 1e-6
    assert tyre.mu(s_p, speed, 4000.0) == pytest.approx(mu_p)


def test_rudd_ekf_matches_filterpy_with_the_same_pseudo_noise() -> None:
    from filterpy.kalman import ExtendedKalmanFilter as FpEKF

    rng = np.random.default_rng(7100)
    s = (np.arange(1, 41) / 40.0) ** 2
    mu = rudd_mu(s, 0.35, 0.15) + rng.normal(0.0, 0.04, 40)
    x0, P0 = np.array([0.6, 0.2]), np.diag([0.5**2, 0.1**2])
    ours = rudd_ekf(s, mu, 0.04, x0, P0)
    fp = FpEKF(dim_x=2, dim_z=1)
    fp.x, fp.P, fp.Q = x0.copy()[:, None], P0.copy(), np.zeros((2, 2))
    for k in range(s.size):
        h_mm, h_ss, h_ms = rudd_hessian(s[k], fp.x[0, 0], fp.x[1, 0])
        p_m, p_s = fp.P[0, 0], fp.P[1, 1]
        pseudo = (0.5 * h_mm * p_m) ** 2 + (0.5 * h_ss * p_s) ** 2 + h_ms**2 * p_m * p_s
        fp.update(
            np.array([[mu[k]]]),
            lambda x, k=k: rudd_jacobian(s[k], x[0, 0], x[1, 0])[None, :],
            lambda x, k=k: np.array([[rudd_mu(s[k], x[0, 0], x[1, 0])]]),
            R=np.array([[(3 * 0.04) ** 2 + pseudo]]),
        )
        np.testing.assert_allclose(ours.x_filt[k], fp.x[:, 0], rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(ours.P_filt[-1], fp.P, rtol=1e-4, atol=1e-9)


def _point_set(path: Path, slip: np.ndarray, mu: np.ndarray) -> Path:
    import pandas as pd

    pd.DataFrame({"time [s]": np.arange(slip.size, dtype=float),
                  "slip_ratio": slip, "drag_force [N]": mu * 4000.0,
                  "normal_force [N]": np.full(slip.size, 4000.0)}).to_csv(path, index=False)
    return path


def test_a_family_of_the_curves_own_shape_beats_the_spline() -> None:
    """The smoothing spline competes held-out with the families; where the points follow
    a family (a dense ramp of a Magic-Formula tyre, or the paper's 40 noisy points of the
    two-parameter curve) the family wins and its peak is the answer; a curve still
    rising at its largest slip gives the spline no peak."""
    rng = np.random.default_rng(8150)
    s = np.concatenate([np.linspace(0.0, 0.08, 800), np.linspace(0.08, 0.6, 400)])
    mf = fit_families(s, magic_formula_mu(s, 12.0, 1.65, 1.1) + rng.normal(0, 0.03, s.size),
                      spline=True)
    assert [f.name for f in mf][-1] == SPLINE
    best = best_fit(mf)
    assert best.name == "magic-formula"
    assert abs(best.slip_peak - magic_formula_peak(12.0, 1.65, 1.1)[1]) < 0.003
    for _ in range(5):
        s = (np.arange(1, 41) / 40.0) ** 2
        paper = fit_families(s, rudd_mu(s, 0.35, 0.15) + rng.normal(0.0, 0.04, 40),
                             spline=True)
        assert best_fit(paper).name != SPLINE
    s = np.linspace(0.0, 0.1, 500)
    rising = fit_families(s, rudd_mu(s, 1.0, 0.2) + rng.normal(0, 0.01, s.size), spline=True)
    assert SPLINE not in [f.name for f in rising]


def test_the_papers_forty_points_through_the_cli(tmp_path: Path) -> None:
    """Rudd's case as a file: 40 noisy (slip, μ) points up to slip 0.948, no time ramp;
    the EKF ends within 1σ of the truth (μp 0.35, sp 0.15)."""
    from typer.testing import CliRunner

    from brakethermo.cli import app

    rng = np.random.default_rng(7101)
    s = np.sort(rng.uniform(0.01, 0.948, 40))
    mu = rudd_mu(s, 0.35, 0.15) + rng.normal(0.0, 0.04, 40)
    path = _point_set(tmp_path / "paper.csv", s, mu)
    res = CliRunner().invoke(app, ["mu-slip", str(path), "--points", "--mu-max", "1.0",
                                   "--out", str(tmp_path / "o"), "--json"])
    assert res.exit_code == 0, res.output
    ekf = json.loads(res.stdout)["ekf"]
    assert abs(ekf["mu_peak"] - 0.35) < ekf["mu_peak_std"] + 0.02
    assert abs(ekf["slip_peak"] - 0.15) < ekf["slip_peak_std"] + 0.02
    # points that never pass the peak: one clear line
    s_low = np.sort(rng.uniform(0.01, 0.12, 40))
    low = _point_set(tmp_path / "low.csv", s_low,
                     rudd_mu(s_low, 0.35, 0.15) + rng.normal(0.0, 0.01, 40))
    res = CliRunner().invoke(app, ["mu-slip", str(low), "--points", "--out",
                                   str(tmp_path / "o")])
    assert res.exit_code == 1 and "never passes the μ peak" in res.output
    assert "Traceback" not in res.output


def test_a_plain_slip_mu_table_is_a_point_set(tmp_path: Path) -> None:
    """The paper's case as people keep it: two columns, slip and μ, no time, no forces, in
    any row order. Same peak as the same points sorted by slip with a time column and
    forces; the page does not call a curve that fits as well as the best family a wrong
    shape."""
    import pandas as pd
    from typer.testing import CliRunner

    from brakethermo.cli import app

    rng = np.random.default_rng(7102)
    s = rng.uniform(0.01, 0.948, 40)  # unsorted, as a table may be
    mu = rudd_mu(s, 0.35, 0.15) + rng.normal(0.0, 0.04, 40)
    plain = tmp_path / "plain.csv"
    pd.DataFrame({"slip": s, "mu": mu}).to_csv(plain, index=False)
    order = np.argsort(s)
    full = _point_set(tmp_path / "full.csv", s[order], mu[order])  # sorted: same points
    out = {}
    for name, path in (("plain", plain), ("full", full)):
        res = CliRunner().invoke(app, ["mu-slip", str(path), "--points", "--mu-max", "1.0",
                                       "--out", str(tmp_path / name), "--json"])
        assert res.exit_code == 0, res.output
        out[name] = json.loads(res.stdout)
    assert out["plain"]["ekf"]["mu_peak"] == pytest.approx(out["full"]["ekf"]["mu_peak"],
                                                            rel=1e-9)
    mm = out["plain"]["shape_mismatch"]  # the points come from the two-parameter curve
    assert mm["rudd_heldout_rmse"] <= 1.05 * mm["best_heldout_rmse"]
    assert "wrong shape" not in mm["words"]
    # without --points a table with no time is refused in one line
    res = CliRunner().invoke(app, ["mu-slip", str(plain), "--out", str(tmp_path / "x")])
    assert res.exit_code == 1 and "Traceback" not in res.output
    assert "pass --points" in res.output  # it said 'the file has: mu' (slip read as time)


def test_a_point_table_in_per_cent_is_named_and_its_label_honoured(tmp_path: Path) -> None:
    """μ or slip written in per cent without a unit: one line saying so; the same column
    labelled '[%]' gives the peak of the plain table."""
    import pandas as pd
    from typer.testing import CliRunner

    from brakethermo.cli import app

    rng = np.random.default_rng(7103)
    s = np.sort(rng.uniform(0.01, 0.948, 40))
    mu = rudd_mu(s, 0.35, 0.15) + rng.normal(0.0, 0.04, 40)
    cases = {"mu_pct": ({"slip": s, "mu": 100 * mu}, "friction_coefficient"),
             "slip_pct": ({"slip": 100 * s, "mu": mu}, "per cent")}
    for name, (cols, phrase) in cases.items():
        path = tmp_path / f"{name}.csv"
        pd.DataFrame(cols).to_csv(path, index=False)
        res = CliRunner().invoke(app, ["mu-slip", str(path), "--points", "--out",
                                       str(tmp_path / name)])
        assert res.exit_code == 1 and "Traceback" not in res.output
        text = " ".join(res.output.split())
        assert phrase in text and "'[%]'" in text, res.output
    peaks = []
    for name, header in (("plain", "slip"), ("labelled", "slip [%]")):
        path = tmp_path / f"{name}.csv"
        pd.DataFrame({header: s if name == "plain" else 100 * s, "mu": mu}).to_csv(
            path, index=False)
        res = CliRunner().invoke(app, ["mu-slip", str(path), "--points", "--json", "--out",
                                       str(tmp_path / f"o_{name}")])
        assert res.exit_code == 0, res.output
        peaks.append(json.loads(res.stdout)["ekf"]["mu_peak"])
    assert peaks[0] == pytest.approx(peaks[1], rel=1e-6)  # x100 then x0.01: rounding only


def test_a_vehicle_speed_in_kmh_labelled_ms_is_named(tmp_path: Path) -> None:
    """The free-rolling check blamed wheel_speed and asked for another radius when the
    vehicle speed was logged in km/h under an m/s label; it names that channel and unit."""
    import dataclasses

    from brakethermo.errors import DataError
    from brakethermo.io.writers import write_session

    sim = simulate_tyre_rig("dry", seed=8107)
    chs = tuple(dataclasses.replace(c, value=c.value * 3.6) if c.name == "vehicle_speed"
                else c for c in sim.session.channels)
    path = write_session(tmp_path / "kmh.mcap", dataclasses.replace(sim.session, channels=chs))
    with pytest.raises(DataError, match="vehicle_speed looks like km/h labelled m/s") as err:
        mu_slip(path)
    assert err.value.channel == "vehicle_speed"


def test_a_session_without_a_radius_takes_it_from_its_free_rolling(tmp_path: Path) -> None:
    """A log with no wheel_radius_m fact was refused while its own free-rolling speeds gave
    the radius, 0.300 m, and the message said so (new-user test): the radius is taken from
    them, and said; the peak is the one the right --radius gives."""
    sim = simulate_tyre_rig("dry", seed=8106)
    facts = {k: v for k, v in sim.session.facts.items() if k != "wheel_radius_m"}
    path = write_session(tmp_path / "no_radius.parquet", SessionData(sim.session.channels,
                                                                      facts))
    taken = summary(mu_slip(path))
    assert taken["wheel_radius_m"] == pytest.approx(float(sim.session.facts["wheel_radius_m"]),
                                                    rel=0.01)
    assert any("taken from its free-rolling speeds" in w for w in taken["warnings"])
    given = summary(mu_slip(path, MuSlipOptions(radius_m=taken["wheel_radius_m"])))
    assert taken["peak"]["mu"] == pytest.approx(given["peak"]["mu"])


def test_a_free_rolling_radius_no_tyre_rig_has_is_said_with_the_likely_unit(
        tmp_path: Path) -> None:
    """A log without a radius whose carriage speed is km/h labelled m/s: 1.081 m was taken
    from its free rolling, no word. Now a warning names km/h and the 0.300 m it gives."""
    from brakethermo.pipelines.mu_slip import _implausible_radius

    said = " ".join(_implausible_radius(1.081))
    assert "outside a tyre rig's 0.15-0.6 m" in said and "km/h labelled m/s" in said
    assert "0.300 m" in said
    assert "m/s labelled km/h" in " ".join(_implausible_radius(0.0834))
    assert _implausible_radius(0.30) == []
    sim = simulate_tyre_rig("dry", seed=8106)
    facts = {k: v for k, v in sim.session.facts.items() if k != "wheel_radius_m"}
    path = write_session(tmp_path / "no_radius.parquet", SessionData(sim.session.channels,
                                                                      facts))
    assert not any("outside a tyre rig" in w for w in summary(mu_slip(path))["warnings"])
