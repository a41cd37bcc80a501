"""Robustness (gaps, dropout, spike, bad start, non-PD covariances), consistency, invariants."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_estimation_ukf import N_NODES, conduction_step

from brakethermo.errors import DataError
from brakethermo.estimation import (
    CovarianceGuard,
    UnscentedKalmanFilter,
    augment_random_walk,
    merwe_weights,
    sigma_points,
    urts_smooth,
)

K = 600
SPOT = 3


def scenario(seed: int = 0):
    """Truth and one noisy spot of the augmented conduction model (h a random walk)."""
    rng = np.random.default_rng(seed)
    q = np.where((np.arange(K) % 60) < 10, 60.0, 0.0)
    f, Q = augment_random_walk(
        lambda X, Th, k: conduction_step(X, Th, k, q), N_NODES, np.eye(N_NODES) * 0.05, [1e-4]
    )
    n = N_NODES + 1
    x = np.r_[np.full(N_NODES, 120.0), 1.2]
    truth = np.empty((K, n))
    for k in range(K):
        truth[k] = x
        x = f(x[None], k)[0] + rng.multivariate_normal(np.zeros(n), Q)
    H = np.zeros((1, n))
    H[0, SPOT] = 1.0
    R = np.eye(1)
    y = truth[:, [SPOT]] + rng.normal(0.0, 1.0, (K, 1))
    x0 = np.r_[np.full(N_NODES, 120.0), 1.0]
    P0 = np.diag(np.r_[np.full(N_NODES, 4.0), 0.1])
    return f, Q, H, R, y, truth, x0, P0


def node_error(res, truth, sl=slice(None)):
    return float(np.sqrt(np.mean((res.x_filt[sl, :N_NODES] - truth[sl, :N_NODES]) ** 2)))


@pytest.fixture(scope="module")
def base():
    f, Q, H, R, y, truth, x0, P0 = scenario()
    ukf = UnscentedKalmanFilter(f, Q, R, H=H)
    res = ukf.run(x0, P0, y, store="diag")
    return ukf, y, truth, x0, P0, res


def test_baseline_tracks_truth(base):
    _ukf, _y, truth, _x0, _P0, res = base
    assert node_error(res, truth) < 1.5
    assert res.n_repairs == 0


def test_nan_gaps_are_predict_only_steps(base):
    ukf, y, truth, x0, P0, res = base
    yg = y.copy()
    yg[np.random.default_rng(1).random(K) < 0.15] = np.nan
    rg = ukf.run(x0, P0, yg, store="diag")
    assert np.all(np.isfinite(rg.x_filt))
    assert np.all(rg.n_obs[np.isnan(yg[:, 0])] == 0)
    assert np.all(np.isnan(rg.nis[np.isnan(yg[:, 0])]))
    assert node_error(rg, truth) < 1.3 * node_error(res, truth) + 0.2


def test_twenty_second_dropout_recovers(base):
    ukf, y, truth, x0, P0, res = base
    yd = y.copy()
    yd[200:400] = np.nan  # 20 s at 10 Hz
    rd = ukf.run(x0, P0, yd, store="smoother")
    assert np.all(np.isfinite(rd.x_filt))
    # the band widens during the dropout and contracts when data return
    assert rd.var_filt[399, SPOT] > 3 * rd.var_filt[199, SPOT]
    assert rd.var_filt[480, SPOT] < 1.5 * res.var_filt[480, SPOT]
    late = slice(450, K)
    assert node_error(rd, truth, late) < 1.5 * node_error(res, truth, late) + 0.3
    sm = urts_smooth(rd)
    assert np.all(np.isfinite(sm.x_smooth))


@pytest.mark.parametrize("gate", [None, 0.9999])
def test_measurement_spike_does_not_derail(base, gate):
    ukf0, y, truth, x0, P0, res = base
    ys = y.copy()
    ys[300] += 400.0
    ukf = UnscentedKalmanFilter(ukf0.f, ukf0.Q, ukf0.R, H=ukf0.H, gate=gate)
    rs = ukf.run(x0, P0, ys, store="diag")
    assert np.all(np.isfinite(rs.x_filt))
    after = slice(360, K)
    assert node_error(rs, truth, after) < 1.3 * node_error(res, truth, after) + 0.2
    if gate is not None:
        assert rs.rejected[300] and rs.rejected.sum() <= 3
        assert abs(rs.x_filt[300, SPOT] - truth[300, SPOT]) < 5.0


def test_bad_initial_state_converges(base):
    ukf, y, truth, x0, _P0, res = base
    bad = x0.copy()
    bad[:N_NODES] -= 80.0
    Pbad = np.diag(np.r_[np.full(N_NODES, 100.0**2), 0.1])
    rb = ukf.run(bad, Pbad, y, store="diag")
    assert abs(rb.x_filt[0, SPOT] - truth[0, SPOT]) < 5.0
    late = slice(300, K)
    assert node_error(rb, truth, late) < 1.5 * node_error(res, truth, late) + 0.3


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_non_pd_covariances_are_repaired_and_counted(base, backend):
    ukf0, y, _truth, x0, P0, _res = base
    Pneg = P0.copy()
    Pneg[0, 0] = -5.0  # not a covariance
    Pneg[0, 1] = Pneg[1, 0] = 3.0
    ukf = UnscentedKalmanFilter(ukf0.f, ukf0.Q, ukf0.R, H=ukf0.H, backend=backend)
    r1 = ukf.run(x0, Pneg, y[:100])
    assert r1.n_repairs >= 1 and r1.repair_steps[0] == 0
    assert np.all(np.isfinite(r1.x_filt)) and np.all(r1.var_filt > 0)
    Qbad = ukf0.Q.copy()
    Qbad[2, 2] = -1.0  # keeps pushing P indefinite
    r2 = UnscentedKalmanFilter(ukf0.f, Qbad, ukf0.R, H=ukf0.H, backend=backend).run(x0, P0, y[:100])
    assert r2.n_repairs > 10
    assert np.all(np.isfinite(r2.x_filt))
    assert len(r2.repair_steps) == r2.n_repairs


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_model_returning_nan_stops_with_a_clear_error(backend):
    def f(X, k):
        return X * (np.nan if k == 5 else 0.9)

    ukf = UnscentedKalmanFilter(f, np.eye(2), np.eye(1), H=np.ones((1, 2)), backend=backend)
    with pytest.raises(DataError, match="non-finite at step 6"):
        ukf.run(np.zeros(2), np.eye(2), np.ones((10, 1)))


def test_consistency_nis_and_coverage():
    """On the model that generated the data: mean NIS ~ m and 95 % bands cover ~95 %."""
    rng = np.random.default_rng(7)
    n, m, Kc = 4, 2, 3000
    A = np.array(
        [[0.95, 0.03, 0, 0], [0.03, 0.9, 0.05, 0], [0, 0.05, 0.9, 0.02], [0, 0, 0.1, 0.85]]
    )
    Q = np.diag([0.5, 0.3, 0.3, 0.2])
    H = np.array([[1.0, 0, 0, 0], [0, 0, 0.5, 0.5]])
    R = np.diag([0.4, 0.6])
    u = np.where((np.arange(Kc) % 100) < 20, 5.0, 0.0)

    def f(X, k):
        return X @ A.T + np.array([u[k], 0, 0, 0]) + 0.002 * np.sin(X)

    x = np.zeros(n)
    truth, y = np.empty((Kc, n)), np.empty((Kc, m))
    for k in range(Kc):
        truth[k] = x
        y[k] = rng.multivariate_normal(H @ x, R)
        x = f(x[None], k)[0] + rng.multivariate_normal(np.zeros(n), Q)
    res = UnscentedKalmanFilter(f, Q, R, H=H).run(np.zeros(n), np.eye(n), y)
    assert abs(np.mean(res.nis) / m - 1.0) < 0.1
    z_f = np.abs(res.x_filt - truth) / np.sqrt(res.var_filt)
    assert 0.93 < np.mean(z_f < 1.96) < 0.97
    sm = urts_smooth(res)
    z_s = np.abs(sm.x_smooth - truth) / np.sqrt(sm.var_smooth)
    assert 0.93 < np.mean(z_s < 1.96) < 0.97
    assert np.mean((sm.x_smooth - truth) ** 2) < np.mean((res.x_filt - truth) ** 2)


@st.composite
def symmetric(draw):
    n = draw(st.integers(1, 8))
    seed = draw(st.integers(0, 2**31))
    shift = draw(st.floats(-3.0, 3.0))
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(n, n))
    return 0.5 * (B + B.T) + shift * np.eye(n)


@settings(max_examples=60, deadline=None)
@given(symmetric())
def test_guard_always_returns_a_valid_factor(P):
    guard = CovarianceGuard()
    L, Pr = guard.cholesky(P.copy(), 0)
    assert np.all(np.isfinite(L))
    np.testing.assert_allclose(L @ L.T, Pr, atol=1e-9 * max(1.0, np.abs(Pr).max()))
    np.testing.assert_array_equal(Pr, Pr.T)
    if np.linalg.eigvalsh(P).min() > 1e-8:
        assert guard.n_repairs == 0
        np.testing.assert_array_equal(Pr, P)
    else:
        assert guard.n_repairs == 1


@settings(max_examples=40, deadline=None)
@given(
    st.integers(1, 7),
    st.integers(0, 2**31),
    st.floats(0.05, 1.0),
    st.floats(0.0, 3.0),
)
def test_unscented_transform_is_exact_for_linear_maps(n, seed, alpha, kappa):
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(n, n))
    P = B @ B.T + 0.1 * np.eye(n)
    m = rng.normal(size=n)
    A = rng.normal(size=(3, n))
    w = merwe_weights(n, alpha, 2.0, kappa)
    X = sigma_points(m, np.linalg.cholesky(P), w.c)
    Y = X @ A.T
    mu = w.Wm @ Y
    D = Y - mu
    scale = 1.0 / alpha**2
    np.testing.assert_allclose(mu, A @ m, atol=1e-10 * scale * (1 + np.abs(Y).max()))
    np.testing.assert_allclose(
        (D.T * w.Wc) @ D, A @ P @ A.T, atol=1e-9 * scale * (1 + np.abs(A @ P @ A.T).max())
    )
