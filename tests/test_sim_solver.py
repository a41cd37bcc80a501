"""Truth-disc conduction solver against analytic solutions and energy conservation."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import i0, i1, k0, k1

from brakethermo.sim.session import SimConfig, simulate
from brakethermo.sim.truth_disc import Boundary, TruthDisc, make_grid

R_IN, R_OUT, S = 0.100, 0.170, 0.008
RHO, C, K = 1850.0, 1200.0, 40.0


def _const(value: float):
    return lambda T: np.full(np.shape(T), value)


def _fin_analytic(r, q, h, h_in, h_out, k, b):
    """Steady annular fin, face flux q and convection h, Robin rims (theta = T - T_amb)."""
    m = np.sqrt(h / (k * b))
    theta_p = q / h
    # k theta'(r_in) = h_in theta(r_in);  -k theta'(r_out) = h_out theta(r_out)
    a = np.array(
        [
            [
                k * m * i1(m * R_IN) - h_in * i0(m * R_IN),
                -k * m * k1(m * R_IN) - h_in * k0(m * R_IN),
            ],
            [
                -k * m * i1(m * R_OUT) - h_out * i0(m * R_OUT),
                k * m * k1(m * R_OUT) - h_out * k0(m * R_OUT),
            ],
        ]
    )
    A, B = np.linalg.solve(a, [h_in * theta_p, h_out * theta_p])
    return theta_p + A * i0(m * r) + B * k0(m * r)


def _steady(
    nr: int, q: float, h: float, h_in: float, h_out: float
) -> tuple[np.ndarray, np.ndarray]:
    grid = make_grid(R_IN, R_OUT, S, nr=nr, nz=2)
    # Through-thickness conduction so fast that the half disc is a thin fin.
    model = TruthDisc(grid, RHO, _const(C), _const(K), kz_ratio=1e5, emissivity=0.0)
    T = np.zeros((grid.nr, grid.nz))
    tf, tr = model.initial_surfaces(T)
    bc = Boundary(q_face=np.full(grid.nr, q), h_face=h, h_inner=h_in, h_outer=h_out, t_amb=0.0)
    T, tf, tr, _ = model.step(T, 1e12, bc, tf, tr)  # one huge implicit step: steady state
    return grid.r_centres, T.mean(axis=1)


def test_steady_annular_fin_matches_bessel_solution_and_converges():
    q, h, h_in, h_out = 5e4, 150.0, 500.0, 300.0
    errors = []
    for nr in (8, 16, 32, 64):
        r, T = _steady(nr, q, h, h_in, h_out)
        exact = _fin_analytic(r, q, h, h_in, h_out, K, S / 2)
        errors.append(np.max(np.abs(T - exact)))
    assert errors[-1] < 0.05  # K, on a ~300 K profile
    assert all(e2 < e1 for e1, e2 in itertools.pairwise(errors))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.7)  # second-order finite volumes


def test_lumped_cooling_transient_converges_first_order_in_time():
    h, t0, t_end = 120.0, 500.0, 120.0
    grid = make_grid(R_IN, R_OUT, S, nr=6, nz=2)
    model = TruthDisc(grid, RHO, _const(C), _const(1e5), kz_ratio=1.0, emissivity=0.0)
    area = grid.ring_areas.sum() + model.rim_area_in.sum() + model.rim_area_out.sum()
    tau = RHO * C * grid.volumes.sum() / (h * area)
    exact = t0 * np.exp(-t_end / tau)
    errors = []
    for dt in (8.0, 4.0, 2.0, 1.0, 0.5):
        T = np.full((grid.nr, grid.nz), t0)
        tf, tr = model.initial_surfaces(T)
        bc = Boundary(q_face=np.zeros(grid.nr), h_face=h, h_inner=h, h_outer=h, t_amb=0.0)
        for _ in range(round(t_end / dt)):
            T, tf, tr, _ = model.step(T, dt, bc, tf, tr)
        errors.append(abs(T.mean() - exact))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 1.8) and np.all(ratios < 2.2)  # backward Euler: first order
    assert errors[-1] / exact < 0.01


def test_energy_balance_over_a_session_within_one_percent():
    result = simulate(SimConfig(track="tight-like", laps=1, seed=4))
    meta = json.loads(result.truth.schema.metadata[b"brakethermo_truth"])
    e = meta["energy_J"]
    out = e["face_convection"] + e["face_radiation"] + e["rim_convection"] + e["rim_radiation"]
    # Stored change comes from the enthalpy integral of the final field, not the stepping.
    assert abs(e["heat_in"] - out - e["stored"]) / e["heat_in"] < 0.01
    assert e["stored"] > 0 and out > 0
    # Heat in agrees with the truth file's braking power integrated on the 10 Hz grid.
    truth = result.truth.to_pandas()
    q_int = np.trapezoid(truth["q_brake"].to_numpy(np.float64), truth["time"].to_numpy())
    assert q_int == pytest.approx(e["heat_in"], rel=0.01)


@settings(max_examples=30, deadline=None)
@given(
    q=st.floats(0.0, 3e6),
    h=st.floats(10.0, 400.0),
    dt=st.floats(1e-3, 5.0),
    t0=st.floats(0.0, 900.0),
    kz=st.floats(0.05, 2.0),
)
def test_each_step_conserves_energy_exactly(q, h, dt, t0, kz):
    """With constant c the step's own flows balance the enthalpy change to round-off."""
    grid = make_grid(R_IN, R_OUT, S, nr=12, nz=4)
    model = TruthDisc(grid, RHO, _const(C), lambda T: 40.0 - 0.01 * T, kz_ratio=kz, emissivity=0.85)
    T = np.full((grid.nr, grid.nz), t0) + np.linspace(0, 50, grid.nr)[:, None]
    tf, tr = model.initial_surfaces(T)
    q_face = np.where(grid.r_centres > 0.122, q, 0.0)
    bc = Boundary(q_face=q_face, h_face=h, h_inner=0.6 * h, h_outer=1.3 * h, t_amb=25.0)
    T1, _, _, flows = model.step(T, dt, bc, tf, tr)
    stored = model.enthalpy(T1) - model.enthalpy(T)
    scale = max(abs(flows).max(), abs(stored), 1.0)
    assert abs(flows[0] - flows[1:].sum() - stored) / scale < 1e-6


def test_compiled_step_inputs_equal_the_per_sample_quantities():
    """The coupled loop's compiled step means (heat per crown, face h) are the trapezoid
    means of exactly what the truth file records per sample."""
    from brakethermo.sim.brake_chain import draw_brake_chain
    from brakethermo.sim.effects import EFFECT_NAMES, make_effects
    from brakethermo.sim.heat import HLaw, crown_weights
    from brakethermo.sim.ride_and_heat import _Context, _derive, _geo, _step_inputs
    from brakethermo.sim.track import load_track
    from brakethermo.sim.vehicle import VehicleSpec
    from brakethermo.thermal.disc import load_disc

    rng = np.random.default_rng(0)
    track, disc, laps = load_track("tight-like"), load_disc("cc-340-8"), 2
    eff = make_effects({n: 1.0 for n in EFFECT_NAMES}, rng)
    segs = track.segments
    ctx = _Context(
        track=track, laps=laps, disc=disc, veh=VehicleSpec(),
        chain=draw_brake_chain(disc, rng), eff=eff, h_law=HLaw(),
        following=np.array([False, True, True]),
        slip_red=rng.uniform(0.2, 0.4, size=(laps + 1, len(segs))),
        w_event=crown_weights(laps + 1, len(track.corners), 0.5, 0.2, rng),
        seg_ends=np.cumsum([sg.length for sg in segs]),
        seg_straight=np.array([sg.kind == "straight" for sg in segs]),
        corner_ends=track.corner_spans()[:, 1],
    )
    for _ in range(200):
        n = 26
        s = rng.uniform(0.0, (laps + 1) * track.length - 50.0) + np.linspace(0, 4.0, n)
        v = rng.uniform(30.0, 95.0) + rng.normal(0.0, 0.5, n)
        torque = np.maximum(rng.uniform(-300.0, 500.0) + rng.normal(0.0, 50.0, n), 0.0)
        d = _derive(ctx, v, s, torque)
        qw, h = _step_inputs(v, s, torque, _geo(ctx), ctx.corner_ends, ctx.seg_ends,
                             ctx.seg_straight, ctx.following, ctx.slip_red, ctx.w_event)
        tw = np.full(n, 1.0)
        tw[[0, -1]] = 0.5
        assert h == pytest.approx(np.sum(tw * d["h"]) / (n - 1), rel=1e-12)
        ref = np.sum(tw[:, None] * np.nan_to_num(d["w"]) * d["q"][:, None], axis=0) / (n - 1)
        assert np.allclose(qw, ref, rtol=1e-12, atol=1e-9)
