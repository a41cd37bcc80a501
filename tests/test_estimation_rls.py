"""RLS with forgetting factor (paper 004, eq. 12a-d) against closed-form answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.errors import ConfigError
from brakethermo.estimation.rls import even_powers, rls_fit


def test_recovers_even_polynomial_exactly_on_noise_free_data():
    s = np.linspace(0.0, 1.2, 400)
    w_true = np.array([2.0, -0.7, 0.4, 0.05])
    X = even_powers(s)
    res = rls_fit(X, X @ w_true, lam=1.0, delta=1e-10)
    np.testing.assert_allclose(res.w, w_true, rtol=0, atol=1e-6)
    assert np.max(np.abs(X @ res.w - X @ w_true)) < 1e-8


def test_lambda_one_is_the_ridge_solution_and_tends_to_lstsq():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(300, 4)) * np.array([1.0, 10.0, 0.1, 3.0])
    y = X @ np.array([1.0, -0.2, 5.0, 0.3]) + 0.1 * rng.normal(size=300)
    delta = 1e-3
    res = rls_fit(X, y, lam=1.0, delta=delta)
    scale = np.sqrt(np.mean(X * X, axis=0))
    Xs = X / scale
    ridge = np.linalg.solve(Xs.T @ Xs + delta * np.eye(4), Xs.T @ y) / scale
    np.testing.assert_allclose(res.w, ridge, rtol=1e-9, atol=1e-12)
    lstsq = np.linalg.lstsq(X, y, rcond=None)[0]
    tight = rls_fit(X, y, lam=1.0, delta=1e-8).w
    np.testing.assert_allclose(tight, lstsq, rtol=1e-6, atol=1e-9)
    # a bigger delta is a visibly different (ridge) answer: the test can fail
    assert np.max(np.abs(rls_fit(X, y, lam=1.0, delta=10.0).w - lstsq)) > 1e-3


def test_forgetting_tracks_a_slowly_changing_characteristic():
    rng = np.random.default_rng(7)
    K = 6000
    s = rng.uniform(0.0, 1.0, K)
    gain = np.linspace(1.0, 2.0, K)  # the characteristic stiffens over the session
    y = gain * s**2 + 0.01 * rng.normal(size=K)
    X = even_powers(s, (2,))
    tracked = rls_fit(X, y, lam=0.995).w_history[:, 0]
    frozen = rls_fit(X, y, lam=1.0).w_history[:, 0]
    tail = slice(K - 1000, K)
    assert np.max(np.abs(tracked[tail] - gain[tail])) < 0.05
    assert abs(frozen[-1] - gain[-1]) > 0.3  # lam = 1 averages the whole history


def test_stays_finite_and_symmetric_on_badly_scaled_regressors():
    s = np.linspace(0.0, 30.0, 3000)  # mm: s^8 reaches 6.6e11, s^2 starts at 0
    X = even_powers(s)
    y = X @ np.array([1e-2, -1e-5, 1e-8, 1e-12])
    res = rls_fit(X, y, lam=0.999)
    assert np.isfinite(res.w_history).all() and np.isfinite(res.P).all()
    np.testing.assert_array_equal(res.P, res.P.T)
    d = s[-1] ** np.r_[2.0, 4.0, 6.0, 8.0]  # P in regressor-normalised units is PSD
    assert np.min(np.linalg.eigvalsh(res.P * np.outer(d, d))) > -1e-9
    assert np.max(np.abs(X @ res.w - y)) / np.max(np.abs(y)) < 1e-6


@settings(max_examples=30, deadline=None)
@given(
    w=st.lists(st.floats(-5, 5), min_size=1, max_size=4),
    lam=st.floats(0.95, 1.0),
    seed=st.integers(0, 2**16),
)
def test_property_noise_free_data_is_fitted_exactly(w, lam, seed):
    """Any forgetting factor reproduces a noise-free linear law once excited."""
    rng = np.random.default_rng(seed)
    p = len(w)
    X = rng.normal(size=(60 * p, p))
    y = X @ np.array(w)
    res = rls_fit(X, y, lam=lam, delta=1e-9)
    np.testing.assert_allclose(res.w, w, rtol=0, atol=1e-5 * (1 + np.max(np.abs(w))))
    np.testing.assert_array_equal(res.P, res.P.T)


def test_bad_arguments_are_config_errors():
    X = np.ones((5, 2))
    with pytest.raises(ConfigError, match="forgetting factor"):
        rls_fit(X, np.ones(5), lam=1.5)
    with pytest.raises(ConfigError, match="finite"):
        rls_fit(X, np.r_[np.ones(4), np.nan])
    with pytest.raises(ConfigError, match="needs X"):
        rls_fit(X, np.ones(4))
