"""Unscented RTS smoother against exact linear references; EKF against the linear KF."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from brakethermo.estimation import (
    ExtendedKalmanFilter,
    UnscentedKalmanFilter,
    kalman_filter,
    rts_smoother,
    urts_smooth,
)


def linear_problem(K: int = 200, n: int = 6, seed: int = 0, inputs: bool = True):
    """Constant-property cooling chain x+ = A x + b_k (heat pulses b), two sensors."""
    rng = np.random.default_rng(seed)
    A = np.eye(n) * 0.9
    A += np.diag(np.full(n - 1, 0.04), 1) + np.diag(np.full(n - 1, 0.04), -1)
    Q = np.eye(n) * 0.2 + 0.05
    H = np.zeros((2, n))
    H[0, 1], H[1, 3], H[1, 4] = 1.0, 0.5, 0.5
    R = np.array([[1.0, 0.2], [0.2, 1.5]])
    b = np.zeros((K, n))
    if inputs:
        b[(np.arange(K) % 40) < 8, 2] = 15.0
    x = rng.normal(50.0, 5.0, n)
    y = np.empty((K, 2))
    for k in range(K):
        y[k] = rng.multivariate_normal(H @ x, R)
        x = A @ x + b[k] + rng.multivariate_normal(np.zeros(n), Q)
    y[30:45] = np.nan
    y[70, 0] = np.nan
    x0, P0 = np.full(n, 45.0), np.eye(n) * 30.0
    return A, b, Q, H, R, y, x0, P0


def close(a, b, tol=1e-8):
    np.testing.assert_allclose(a, b, rtol=0, atol=tol * max(1.0, float(np.max(np.abs(b)))))


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("alpha", [1.0, 0.1])
def test_urts_equals_exact_rts_on_linear_model(backend, alpha):
    A, b, Q, H, R, y, x0, P0 = linear_problem()
    ref = kalman_filter(A, Q, H, R, x0, P0, y, b=b)
    x_ref, P_ref = rts_smoother(A, ref)
    res = UnscentedKalmanFilter(
        lambda X, k: X @ A.T + b[k], Q, R, H=H, alpha=alpha, backend=backend
    ).run(x0, P0, y, store="full")
    close(res.x_filt, ref.x_filt)
    close(res.P_filt, ref.P_filt)
    close(res.P_pred, ref.P_pred)
    np.testing.assert_allclose(res.loglik, ref.loglik, rtol=1e-9, atol=1e-9)
    sm = urts_smooth(res, store="full", backend=backend)
    close(sm.x_smooth, x_ref)
    close(sm.P_smooth, P_ref)
    # the smoother can only sharpen the filter
    assert np.all(sm.var_smooth <= res.var_filt + 1e-12)


def test_urts_equals_filterpy_rts_on_input_free_stretch():
    A, _b, Q, H, R, y, x0, P0 = linear_problem(K=150, inputs=False)
    kf = KalmanFilter(dim_x=A.shape[0], dim_z=2)
    kf.F, kf.Q, kf.H, kf.R, kf.x, kf.P = A, Q, H, R, x0.copy(), P0.copy()
    xs, Ps = [], []
    for k in range(y.shape[0]):
        if k > 0:
            kf.predict()
        ok = np.isfinite(y[k])
        if ok.all():
            kf.update(y[k])
        elif ok.any():
            kf.update(y[k, ok], R=R[np.ix_(ok, ok)], H=H[ok])
        else:
            kf.update(None)
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
    x_fp, P_fp, _, _ = kf.rts_smoother(np.array(xs), np.array(Ps))
    res = UnscentedKalmanFilter(lambda X, k: X @ A.T, Q, R, H=H).run(x0, P0, y)
    sm = urts_smooth(res, store="full")
    close(res.x_filt, np.array(xs))
    close(sm.x_smooth, x_fp)
    close(sm.P_smooth, P_fp)


@pytest.mark.parametrize("analytic", [True, False])
def test_ekf_equals_kf_on_linear_model(analytic):
    A, b, Q, H, R, y, x0, P0 = linear_problem()
    ref = kalman_filter(A, Q, H, R, x0, P0, y, b=b)
    ekf = ExtendedKalmanFilter(
        lambda X, k: X @ A.T + b[k], Q, R, H=H, F_jac=(lambda x, k: A) if analytic else None
    )
    res = ekf.run(x0, P0, y, store="full")
    tol = 1e-10 if analytic else 1e-6  # forward differences cost ~sqrt(eps)
    close(res.x_filt, ref.x_filt, tol)
    close(res.P_filt, ref.P_filt, tol)
    # the extended RTS smoother through the same backward pass
    x_ref, P_ref = rts_smoother(A, ref)
    sm = urts_smooth(res, store="full")
    close(sm.x_smooth, x_ref, tol)
    close(sm.P_smooth, P_ref, tol)


def test_ekf_nonlinear_measurement_equals_kf_when_h_is_linear():
    A, b, Q, H, R, y, x0, P0 = linear_problem(K=80)
    ref = kalman_filter(A, Q, H, R, x0, P0, y, b=b)
    res = ExtendedKalmanFilter(
        lambda X, k: X @ A.T + b[k], Q, R, h=lambda X, k: X @ H.T, F_jac=lambda x, k: A
    ).run(x0, P0, y)
    close(res.x_filt, ref.x_filt, 1e-6)


def test_ukf_and_ekf_are_close_on_mildly_nonlinear_model():
    A, b, Q, H, R, y, x0, P0 = linear_problem(K=150)

    def f(X, k):
        return X @ A.T + b[k] - 1e-4 * (X - 50.0) ** 2

    u = UnscentedKalmanFilter(f, Q, R, H=H).run(x0, P0, y, store="diag")
    e = ExtendedKalmanFilter(f, Q, R, H=H).run(x0, P0, y, store="diag")
    assert np.max(np.abs(u.x_filt - e.x_filt)) < 0.5


@pytest.mark.parametrize("analytic", [True, False])
def test_ekf_backends_agree_on_every_output(analytic):
    """The compiled EKF step equals the numpy loop (gaps, gate, readout, all stores)."""
    A, b, Q, H, R, y, x0, P0 = linear_problem(K=120, seed=3)
    y[50, 1] = 40.0  # an outlier for the gate

    def f(X, k):
        return X @ A.T + b[k] - 1e-4 * (X - 50.0) ** 2

    def F_jac(x, k):
        return A - np.diag(2e-4 * (x - 50.0))

    M = np.random.default_rng(1).normal(size=(2, x0.size))
    # a forward difference turns a last-bit difference of x (summation order) into
    # ~1e-8 of the Jacobian: analytic, the paths agree to round-off
    tol = 1e-10 if analytic else 1e-6
    for store in ("full", "smoother", "diag"):
        for gate in (None, 0.999):
            a, c = (
                ExtendedKalmanFilter(f, Q, R, H=H, F_jac=F_jac if analytic else None, gate=gate,
                                     backend=be).run(x0, P0, y, store=store, readout=M)
                for be in ("numpy", "numba")
            )
            for name, va in a.__dict__.items():
                vc = getattr(c, name)
                if isinstance(va, np.ndarray):
                    np.testing.assert_array_equal(np.isnan(va), np.isnan(vc))
                    close(np.nan_to_num(vc), np.nan_to_num(va.astype(float)), tol)
                else:
                    assert va == vc, name
            if store != "diag":
                close(urts_smooth(c, store="full").x_smooth,
                      urts_smooth(a, store="full").x_smooth, tol)
            assert gate is None or a.rejected[50]
