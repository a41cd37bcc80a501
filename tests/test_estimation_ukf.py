"""UKF against filterpy's UnscentedKalmanFilter on the same models and data."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints
from filterpy.kalman import UnscentedKalmanFilter as FilterpyUKF

from brakethermo.errors import ConfigError
from brakethermo.estimation import (
    UnscentedKalmanFilter,
    augment_random_walk,
    merwe_weights,
    urts_smooth,
)

N_NODES = 8
T_AMB = 30.0


def conduction_step(T: np.ndarray, h: np.ndarray, k: int, q: np.ndarray) -> np.ndarray:
    """Toy implicit radial conduction, k(T) lagged, face convection h, heat pulse q[k].

    Each batch member has its own tridiagonal matrix (T- and h-dependent); solved by a
    batched Thomas sweep.
    """
    B, n = T.shape
    cap = 1.0
    kc = 0.05 * (1.0 + 2e-3 * T)  # conductivity rising with temperature
    g = 0.5 * (kc[:, 1:] + kc[:, :-1]) * n * n * 0.01
    hc = 0.02 * h[:, 0]
    diag = np.full((B, n), cap) + hc[:, None]
    diag[:, 1:] += g
    diag[:, :-1] += g
    src = np.zeros(n)
    src[n // 2 - 1 : n // 2 + 2] = [0.5, 1.0, 0.5]
    rhs = cap * T + hc[:, None] * T_AMB + q[k] * src
    c = np.empty((B, n - 1))
    d = np.empty((B, n))
    c[:, 0] = -g[:, 0] / diag[:, 0]
    d[:, 0] = rhs[:, 0] / diag[:, 0]
    for i in range(1, n):
        den = diag[:, i] + g[:, i - 1] * c[:, i - 1]
        if i < n - 1:
            c[:, i] = -g[:, i] / den
        d[:, i] = (rhs[:, i] + g[:, i - 1] * d[:, i - 1]) / den
    for i in range(n - 2, -1, -1):
        d[:, i] -= c[:, i] * d[:, i + 1]
    return d


def heat_problem(K: int = 150, seed: int = 0):
    """Augmented conduction model [T_1..T_N, h], simulated data of two spots with gaps."""
    rng = np.random.default_rng(seed)
    q = np.where((np.arange(K) % 50) < 12, 40.0, 0.0)
    f, Q = augment_random_walk(
        lambda X, Th, k: conduction_step(X, Th, k, q), N_NODES, np.eye(N_NODES) * 0.05, [1e-3]
    )
    x = np.r_[np.full(N_NODES, 150.0), 1.3]
    H = np.zeros((2, N_NODES + 1))
    H[0, 3], H[1, 5], H[1, 6] = 1.0, 0.6, 0.4
    R = np.diag([1.0, 2.0])
    y = np.empty((K, 2))
    for k in range(K):
        y[k] = H @ x + rng.normal(0.0, np.sqrt(np.diag(R)))
        x = f(x[None], k)[0] + rng.multivariate_normal(np.zeros(N_NODES + 1), Q)
    y[min(20, K - 1) : 24] = np.nan
    y[40:41, 1] = np.nan
    y[60:61, 0] = np.nan
    x0 = np.r_[np.full(N_NODES, 140.0), 1.0]
    P0 = np.diag(np.r_[np.full(N_NODES, 25.0), 0.1])
    return f, Q, H, R, y, x0, P0


def run_filterpy(f, Q, R, y, x0, P0, alpha, beta, kappa, H=None, h=None):
    """filterpy UKF from the prior at step 0: update first, then predict/update."""
    n, m = x0.shape[0], y.shape[1]
    pts = MerweScaledSigmaPoints(n, alpha=alpha, beta=beta, kappa=kappa)

    def hx(x, idx=slice(None)):
        z = H @ x if H is not None else h(x[None], 0)[0]
        return z[idx]

    ukf = FilterpyUKF(
        dim_x=n, dim_z=m, dt=1.0, hx=hx, fx=lambda x, dt, k: f(x[None], k)[0], points=pts
    )
    ukf.x, ukf.P, ukf.Q, ukf.R = x0.copy(), P0.copy(), Q, R
    ukf.sigmas_f = pts.sigma_points(x0, P0)  # filterpy's update uses the last predict's set
    xs_p, Ps_p, xs, Ps = [], [], [], []
    for k in range(y.shape[0]):
        if k > 0:
            ukf.predict(k=k - 1)
        xs_p.append(ukf.x.copy())
        Ps_p.append(ukf.P.copy())
        ok = np.isfinite(y[k])
        if not ok.any():
            ukf.update(None)  # filterpy turns a NaN measurement into a NaN state
        elif ok.all():
            ukf.update(y[k])
        else:
            ukf.update(y[k, ok], R=R[np.ix_(ok, ok)], hx=hx, idx=ok)
        xs.append(ukf.x.copy())
        Ps.append(ukf.P.copy())
    return np.array(xs_p), np.array(Ps_p), np.array(xs), np.array(Ps)


def assert_close(a, b, tol=1e-8):
    scale = max(1.0, float(np.max(np.abs(b))))
    np.testing.assert_allclose(a, b, rtol=0, atol=tol * scale)


def assert_same_track(res, reference):
    """Our predicted and filtered means and covariances are filterpy's (``run_filterpy``)."""
    xp, Pp, xf, Pf = reference
    assert_close(res.x_pred, xp)
    assert_close(res.P_pred, Pp)
    assert_close(res.x_filt, xf)
    assert_close(res.P_filt, Pf)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_heat_model_with_random_walk_h_matches_filterpy(backend):
    f, Q, H, R, y, x0, P0 = heat_problem()
    ours = UnscentedKalmanFilter(f, Q, R, H=H, alpha=0.3, beta=2.0, kappa=0.0, backend=backend)
    res = ours.run(x0, P0, y, store="full")
    assert_same_track(res, run_filterpy(f, Q, R, y, x0, P0, 0.3, 2.0, 0.0, H=H))
    assert res.n_repairs == 0
    # h is tracked: the posterior sd of h shrinks from the prior's
    assert res.var_filt[-1, -1] < P0[-1, -1]


def test_nonlinear_measurement_matches_filterpy():
    """A nonlinear h (radiometric-like T^4 reading) uses the redrawn sigma set, as filterpy."""
    f, Q, _H, R, y, x0, P0 = heat_problem(K=80, seed=3)

    def h(X, k):
        T = X[:, [3, 5]] + 273.15
        return (T / 400.0) ** 4 * 100.0

    yy = h(np.full((1, x0.size), 160.0), 0) + np.random.default_rng(1).normal(0, 1, y.shape)
    yy[np.isnan(y)] = np.nan
    res = UnscentedKalmanFilter(f, Q, R, h=h, alpha=0.5, beta=2.0, kappa=1.0).run(
        x0, P0, yy, store="full"
    )
    assert_same_track(res, run_filterpy(f, Q, R, yy, x0, P0, 0.5, 2.0, 1.0, h=h))


def test_backends_agree_on_every_output():
    f, Q, H, R, y, x0, P0 = heat_problem(K=120, seed=5)
    M = np.random.default_rng(0).normal(size=(3, x0.size))
    for store in ("full", "smoother", "diag"):
        for gate in (None, 0.999):
            a, b = (
                UnscentedKalmanFilter(f, Q, R, H=H, gate=gate, backend=be).run(
                    x0, P0, y, store=store, readout=M
                )
                for be in ("numpy", "numba")
            )
            for name, va in a.__dict__.items():
                vb = getattr(b, name)
                if isinstance(va, np.ndarray):
                    np.testing.assert_array_equal(np.isnan(va), np.isnan(vb))
                    assert_close(np.nan_to_num(vb), np.nan_to_num(va.astype(float)), 1e-10)
                else:
                    assert va == vb, name
            if store != "diag":
                sa = urts_smooth(a, store="full", readout=M, backend="numpy")
                sb = urts_smooth(b, store="full", readout=M, backend="numba")
                assert_close(sb.x_smooth, sa.x_smooth, 1e-10)
                assert_close(sb.P_smooth, sa.P_smooth, 1e-10)
                assert_close(sb.readout_var, sa.readout_var, 1e-10)


def test_all_sigma_points_go_through_one_model_call():
    f, Q, H, R, y, x0, P0 = heat_problem(K=30)
    batches = []

    def counting_f(X, k):
        batches.append(X.shape[0])
        return f(X, k)

    UnscentedKalmanFilter(counting_f, Q, R, H=H).run(x0, P0, y)
    assert batches == [2 * x0.size + 1] * (y.shape[0] - 1)


def test_readout_and_store_modes_are_consistent():
    f, Q, H, R, y, x0, P0 = heat_problem(K=60)
    ukf = UnscentedKalmanFilter(f, Q, R, H=H)
    full = ukf.run(x0, P0, y, store="full", readout=H)
    lean = ukf.run(x0, P0, y, store="smoother", store_dtype=np.float32)
    diag = ukf.run(x0, P0, y, store="diag")
    np.testing.assert_allclose(full.readout, full.x_filt @ H.T)
    np.testing.assert_allclose(
        full.readout_var, np.einsum("ij,kjl,il->ki", H, full.P_filt, H), rtol=1e-12
    )
    np.testing.assert_allclose(diag.x_filt, full.x_filt)
    np.testing.assert_allclose(full.var_filt, np.diagonal(full.P_filt, axis1=1, axis2=2))
    assert diag.G is None and diag.P_filt is None
    assert lean.G.dtype == np.float32 and lean.P_filt is None
    s64, s32 = urts_smooth(full), urts_smooth(lean)
    np.testing.assert_allclose(s32.x_smooth, s64.x_smooth, rtol=0, atol=1e-3)
    with pytest.raises(ConfigError):
        urts_smooth(diag)


def test_weights_match_filterpy():
    for n, a, b, k in [(1, 1.0, 2.0, 0.0), (9, 0.1, 2.0, 0.0), (52, 1e-3, 2.0, 3.0 - 52)]:
        w = merwe_weights(n, a, b, k)
        p = MerweScaledSigmaPoints(n, alpha=a, beta=b, kappa=k)
        np.testing.assert_allclose(w.Wm, p.Wm, rtol=1e-12)
        np.testing.assert_allclose(w.Wc, p.Wc, rtol=1e-12)


def test_bad_arguments_raise_config_errors():
    f, Q, H, R, y, x0, P0 = heat_problem(K=5)
    with pytest.raises(ConfigError):
        UnscentedKalmanFilter(f, Q, R)
    with pytest.raises(ConfigError):
        UnscentedKalmanFilter(f, Q, R, H=H, h=lambda X, k: X)
    with pytest.raises(ConfigError):
        UnscentedKalmanFilter(f, Q, R, H=H, gate=1.5)
    with pytest.raises(ConfigError):
        UnscentedKalmanFilter(f, Q, R, H=H).run(x0, P0[:-1, :-1], y)
    with pytest.raises(ConfigError):
        UnscentedKalmanFilter(f, Q[:-1], R, H=H).run(x0, P0, y)
    with pytest.raises(ConfigError):
        UnscentedKalmanFilter(f, Q, R, H=H).run(x0, P0, y, store="everything")
    with pytest.raises(ConfigError):
        merwe_weights(3, alpha=0.0)


@pytest.mark.parametrize("n", [5, 20, 40])
def test_backends_agree_across_kernel_size_branches(n):
    """The compiled kernel loops for small n and calls BLAS above; both equal numpy."""
    rng = np.random.default_rng(n)
    A = np.eye(n) * 0.9 + rng.normal(0.0, 0.02, (n, n))

    def f(X, k):
        return X @ A.T + 0.05 * np.sin(X) + 0.1 * k

    Q = np.eye(n) * 0.1
    H = rng.normal(size=(2, n)) / n
    R = np.eye(2) * 0.5
    y = rng.normal(size=(80, 2))
    y[10:15] = np.nan
    runs = [
        UnscentedKalmanFilter(f, Q, R, H=H, backend=be).run(
            np.zeros(n), np.eye(n), y, store="full", store_dtype=np.float64
        )
        for be in ("numpy", "numba")
    ]
    for name in ("x_pred", "x_filt", "P_pred", "P_filt", "cross", "G", "Sigma", "loglik"):
        assert_close(getattr(runs[1], name), getattr(runs[0], name), 1e-8)


@pytest.mark.parametrize("n", [40])
def test_one_spot_update_by_rank1_downdate_matches_filterpy(n):
    """From n = 32 the numpy path downdates the prior's factor into the posterior's and
    forms the gains by triangular solves; filterpy factors and inverts afresh."""
    rng = np.random.default_rng(n)
    A = np.eye(n) * 0.9 + rng.normal(0.0, 0.02, (n, n))

    def f(X, k):
        return X @ A.T + 0.05 * np.sin(X) + 0.1 * k

    Q = np.eye(n) * 0.1 + 0.02
    H = rng.normal(size=(1, n)) / n
    R = np.eye(1) * 0.5
    y = rng.normal(size=(60, 1))
    y[10:15] = np.nan  # predict-only steps keep the prior's factor
    x0, P0 = np.zeros(n), np.eye(n) * 4.0
    res = UnscentedKalmanFilter(f, Q, R, H=H, alpha=0.5, backend="numpy").run(
        x0, P0, y, store="full", store_dtype=np.float64
    )
    assert_same_track(res, run_filterpy(f, Q, R, y, x0, P0, 0.5, 2.0, 0.0, H=H))
    assert res.n_repairs == 0
    G = np.einsum("kij,kjl->kil", res.cross, np.linalg.inv(res.P_pred[1:]))
    assert_close(res.G, G)
    # the reference goes through an explicit inverse: compared at its own precision
    assert_close(res.Sigma, res.P_filt[:-1] - np.einsum("kij,kjl,kml->kim", G, res.P_pred[1:], G),
                 1e-6)
