"""Windowed unscented RTS smoother: bounded memory, the whole-session smoother's answer."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.errors import ConfigError
from brakethermo.estimation import UnscentedKalmanFilter, urts_smooth
from brakethermo.estimation.urts import urts_smooth_windowed, window_steps
from brakethermo.thermal.disc import load_disc
from brakethermo.thermal.model import DiscFEModel
from tests.test_estimation_smoother import linear_problem

# the estimate's 95 % band is a few tens of degC wide; "a small fraction" of it
BAND_FRACTION_C = 1e-6


def _linear(backend: str):
    A, b, Q, H, R, y, x0, P0 = linear_problem(K=120)
    ukf = UnscentedKalmanFilter(lambda X, k: X @ A.T + b[k], lambda k: Q, R, H=H,
                                backend=backend)
    return ukf, x0, P0, y, H


@pytest.fixture(scope="module")
def disc_case():
    """A layered disc model (n = 24) braking every 6 s, spot 3 measured, 700 steps."""
    disc = load_disc()
    model = DiscFEModel(disc, 8, 3, layer_growth=2.0)
    K = 700
    q = np.where((np.arange(K) % 60) < 15, 4.0e4, 0.0)
    H = model.spot_matrix([disc.spot_radii[2]])

    def f(X, k):
        return model.step(X, q[k], 90.0, 25.0)

    rng = np.random.default_rng(7)
    x = model.initial_state(150.0)
    y = np.empty((K, 1))
    for k in range(K):
        y[k] = H @ x + rng.normal(0.0, 3.0)
        x = f(x[None], k)[0]
    y[200:260] = np.nan  # a dropout across a window boundary
    n = model.n_state
    Q = np.eye(n) * 0.04
    ukf = UnscentedKalmanFilter(f, lambda k: Q * (1.0 + q[k] / 4.0e4), np.array([[9.0]]), H=H,
                                alpha=0.5)
    x0, P0 = model.initial_state(140.0), np.eye(n) * 400.0
    readout = model.spot_matrix(disc.spot_radii)
    ref_f = ukf.run(x0, P0, y, store="smoother", readout=readout)
    ref = urts_smooth(ref_f, readout=readout)
    return ukf, x0, P0, y, readout, ref_f, ref


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@given(window=st.integers(1, 120), workers=st.integers(1, 3))
@settings(max_examples=6, deadline=None)
def test_any_windows_give_the_whole_session_smoother(backend, window, workers):
    ukf, x0, P0, y, H = _linear(backend)
    ref_f = ukf.run(x0, P0, y, store="smoother", readout=H)
    ref = urts_smooth(ref_f, readout=H, backend=backend)
    run = urts_smooth_windowed(ukf, x0, P0, y, readout=H, window=window, workers=workers,
                               backend=backend)
    assert len(run.windows) == -(-y.shape[0] // window)
    np.testing.assert_allclose(run.smoothed.x_smooth, ref.x_smooth, rtol=0, atol=1e-10)
    np.testing.assert_allclose(run.smoothed.var_smooth, ref.var_smooth, rtol=1e-10, atol=0)
    np.testing.assert_allclose(run.smoothed.readout_var, ref.readout_var, rtol=1e-10, atol=0)
    np.testing.assert_allclose(run.smoothed.P_first, ref.P_first, rtol=1e-10, atol=1e-12)
    # the forward record is the whole-session filter's, step for step
    np.testing.assert_allclose(run.forward.readout, ref_f.readout, rtol=0, atol=1e-10)
    np.testing.assert_allclose(run.forward.nis, ref_f.nis, rtol=1e-10, atol=0)
    assert run.forward.log_likelihood == pytest.approx(ref_f.log_likelihood, rel=1e-12)
    assert run.forward.n_repairs == ref_f.n_repairs


@pytest.mark.parametrize("workers", [1, 2])
def test_disc_model_in_bounded_memory_equals_whole_session(disc_case, workers):
    ukf, x0, P0, y, readout, ref_f, ref = disc_case
    n = x0.size
    whole = ref_f.G.nbytes + ref_f.Sigma.nbytes
    budget = whole // 9  # force ~9-18 windows, some across the dropout
    run = urts_smooth_windowed(ukf, x0, P0, y, readout=readout, max_store_bytes=budget,
                               workers=workers)
    assert len(run.windows) >= 9
    assert run.peak_store_bytes <= budget
    assert run.peak_store_bytes >= budget // 3  # the budget is used, not wasted
    err = np.abs(run.smoothed.readout - ref.readout).max()
    assert err < BAND_FRACTION_C
    np.testing.assert_allclose(np.sqrt(run.smoothed.readout_var), np.sqrt(ref.readout_var),
                               rtol=1e-9)
    np.testing.assert_allclose(run.smoothed.x_smooth, ref.x_smooth, rtol=0, atol=1e-9)
    assert run.smoothed.x_smooth.shape == (y.shape[0], n)


def test_whole_session_is_one_window_when_it_fits(disc_case):
    ukf, x0, P0, y, readout, _ref_f, ref = disc_case
    run = urts_smooth_windowed(ukf, x0, P0, y, readout=readout)
    assert run.windows == ((0, y.shape[0]),)
    np.testing.assert_array_equal(run.smoothed.readout, ref.readout)


def test_window_size_bounds_the_gains_whatever_the_mesh():
    # 150 nodes x 4 layers over a 25-lap race: 34 GB as one window
    n, K = 600, 29_307
    w = window_steps(K, n, itemsize=4, max_store_bytes=512 * 2**20, held=3)
    assert 2 * 4 * n * n * w * 3 <= 512 * 2**20 < 2 * 4 * n * n * (w + 1) * 3
    assert window_steps(100, 10, itemsize=8, max_store_bytes=2**30) == 100
    assert window_steps(10**6, 10**4, itemsize=8, max_store_bytes=1) == 2


def test_bad_workers_and_window_are_config_errors():
    ukf, x0, P0, y, _H = _linear("numpy")
    with pytest.raises(ConfigError, match="workers"):
        urts_smooth_windowed(ukf, x0, P0, y, workers=0)
    with pytest.raises(ConfigError, match="window"):
        urts_smooth_windowed(ukf, x0, P0, y, window=0)


def test_checkpoints_of_a_killed_run_are_removed(tmp_path, monkeypatch):
    import subprocess
    import sys
    import tempfile

    from brakethermo.estimation.urts import CHECKPOINT_PREFIX

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    stale = tmp_path / f"{CHECKPOINT_PREFIX}{dead}-abc"
    stale.mkdir()
    (stale / "P0.npy").write_bytes(b"x" * 100)
    live = tmp_path / f"{CHECKPOINT_PREFIX}1-abc"  # pid 1 is always alive
    live.mkdir()
    ukf, x0, P0, y, H = _linear("numpy")
    run = urts_smooth_windowed(ukf, x0, P0, y, readout=H, window=40)
    assert len(run.windows) == 3
    assert not stale.exists() and live.exists()
    assert [p.name for p in tmp_path.iterdir()] == [live.name]  # its own folder is gone too


@pytest.mark.parametrize(("ram", "share", "budget"), [
    (4 * 2**30, 1, 512 * 2**20),  # an eighth below the floor
    (8 * 2**30, 1, 2**30),
    (64 * 2**30, 1, 2 * 2**30),  # capped
    (64 * 2**30, 8, 2**30),  # eight batch workers side by side
    (0, 1, 512 * 2**20),  # memory unknown: the floor
])
def test_default_store_budget_is_an_eighth_of_memory_within_bounds(monkeypatch, ram, share,
                                                                   budget):
    from brakethermo.estimation import urts

    monkeypatch.setattr(urts, "memory_bytes", lambda: ram)
    assert urts.default_store_budget(share) == budget


def test_memory_is_the_machines_or_nothing_when_unreadable(monkeypatch):
    from brakethermo.estimation import urts

    assert urts.memory_bytes() > 2**28  # this machine: more than 256 MiB

    def broken(name):
        raise ValueError(name)

    monkeypatch.setattr(urts.os, "sysconf", broken)
    assert urts.memory_bytes() == 0
