"""The disc filter's compiled step loop equals the UKF's Python loop over ``f`` and ``Q``."""

from __future__ import annotations

import numpy as np
import pytest

from brakethermo.errors import DataError
from brakethermo.estimation import UnscentedKalmanFilter
from brakethermo.estimation.urts import urts_smooth, urts_smooth_windowed
from brakethermo.models.disc import (
    BALANCE_PARAM,
    H_FACTOR_PARAM,
    H_PARAM,
    KZ_PARAM,
    SCALE_PARAM,
    DiscEffects,
    DiscStateSpace,
    RandomWalkParam,
)
from brakethermo.thermal.disc import load_disc
from brakethermo.thermal.model import DiscFEModel

K = 700

CASES = {
    "plain": ((SCALE_PARAM,), DiscEffects()),
    "h state": ((H_PARAM,), DiscEffects()),
    "every online state, μ(T), lag": (
        (SCALE_PARAM, H_FACTOR_PARAM, KZ_PARAM, BALANCE_PARAM),
        DiscEffects(mu_beta=-0.3, mu_t_mid_c=450.0, sensor_tau_s=0.4),
    ),
}
INIT = {H_PARAM: (90.0, 20.0, 0.5, 5.0), SCALE_PARAM: (1.0, 0.1, 0.002, 0.05),
        H_FACTOR_PARAM: (1.0, 0.1, 0.003, 0.1), KZ_PARAM: (1.0, 0.3, 0.002, 0.05),
        BALANCE_PARAM: (0.0, 0.2, 0.003, -0.6)}


def _space(params: tuple[str, ...], effects: DiscEffects, h_given: bool) -> DiscStateSpace:
    rng = np.random.default_rng(7)
    model = DiscFEModel(load_disc(), 8, 3, layer_growth=2.0, kz_ratio=0.3)
    t = np.arange(K) * model.dt
    q = np.where(np.sin(t / 3.0) > 0.6, 60e3, 0.0) * rng.uniform(0.8, 1.2, K)
    walks = [RandomWalkParam(p, *INIT[p][:3], lower=INIT[p][3],
                             off_brake_only=p == H_FACTOR_PARAM) for p in params]
    return DiscStateSpace(model, q, np.full(K, 24.0) + 0.01 * t,
                          np.full(K, 80.0) + 10 * np.cos(t / 5) if h_given else None, walks,
                          sigma_temp=0.5, sigma_crown=0.2, effects=effects, spot_radius=0.15)


def _filters(ssm: DiscStateSpace) -> tuple[UnscentedKalmanFilter, UnscentedKalmanFilter]:
    R = np.array([[4.0]])
    H = ssm.H_measured(0.15)
    steps = ssm.compiled_steps()
    assert steps is not None
    return (UnscentedKalmanFilter(ssm.f, ssm.Q, R, H=H, backend="numba"),
            UnscentedKalmanFilter(ssm.f, ssm.Q, R, H=H, backend="numba", steps=steps))


def _readings(ssm: DiscStateSpace) -> np.ndarray:
    model = ssm.model
    T = model.initial_state(30.0)
    y = np.empty((K, 1))
    spot = model.spot_matrix([0.15])[0]
    for k in range(K):
        y[k, 0] = spot @ T
        T = model.step(T, ssm.q_brk[k] * 1.1, 70.0, 24.0)
    y[::7] = np.nan  # predict-only steps
    return y + np.random.default_rng(3).normal(0, 2.0, y.shape)


@pytest.mark.parametrize("case", list(CASES))
def test_compiled_steps_equal_the_python_loop(case: str) -> None:
    params, effects = CASES[case]
    ssm = _space(params, effects, H_PARAM not in params)
    loop, fused = _filters(ssm)
    x0, P0 = ssm.prior(ssm.model.initial_state(30.0), 5.0)
    y = _readings(ssm)
    a, b = loop.run(x0, P0, y), fused.run(x0, P0, y)
    np.testing.assert_allclose(b.x_filt, a.x_filt, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(b.var_filt, a.var_filt, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(b.innovation, a.innovation, rtol=1e-10, atol=1e-9)
    assert np.ptp(a.x_filt[:, : ssm.n_temp]) > 50.0  # the disc did heat up and cool


@pytest.mark.parametrize("case", list(CASES))
def test_reduced_compiled_steps_equal_the_python_loop(case: str) -> None:
    """The reduced-order filter's compiled loop (lift, the full model's step, project
    back) equals the UKF's Python loop over the reduced ``f`` and ``Q``."""
    from brakethermo.models.reduced import ReducedStateSpace, pod_modes, with_directions

    params, effects = CASES[case]
    ssm = _space(params, effects, H_PARAM not in params)
    x0, P0 = ssm.prior(ssm.model.initial_state(30.0), 5.0)
    snapshots = ssm.model.initial_state(30.0) + np.random.default_rng(5).normal(
        0.0, 40.0, (60, ssm.n_temp))
    Phi, _ = pod_modes(snapshots, 1e-9, 6)
    red = ReducedStateSpace(ssm, with_directions(Phi, ssm.crown_directions()))
    R, H = np.array([[4.0]]), red.H_measured(0.15)
    steps = red.compiled_steps()
    assert steps is not None and red.n < ssm.n
    loop = UnscentedKalmanFilter(red.f, red.Q, R, H=H, backend="numba")
    fused = UnscentedKalmanFilter(red.f, red.Q, R, H=H, backend="numba", steps=steps)
    z0, Pz0 = red.project(x0), red.L.T @ P0 @ red.L
    y = _readings(ssm)
    a, b = loop.run(z0, Pz0, y), fused.run(z0, Pz0, y)
    with pytest.raises(ValueError, match="both the lift and the noise"):
        ssm.compiled_steps(lift=red.L)  # full-size noise indexed in reduced coordinates
    with pytest.raises(ValueError, match="reduced coordinates"):
        ssm.compiled_steps((red._Q_base, red._S_crown, red._param_idx), lift=red.L[:-1])
    # the lift and projection sum in another order than numpy's matrix products
    np.testing.assert_allclose(b.x_filt, a.x_filt, rtol=1e-8, atol=1e-7)
    np.testing.assert_allclose(b.var_filt, a.var_filt, rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(b.innovation, a.innovation, rtol=1e-8, atol=1e-7)


def test_windowed_smoother_counts_the_model_steps_from_each_window() -> None:
    """The bounded-memory smoother re-runs windows from their own first step: the
    compiled loop must step the model from there too (the offset; a window longer than
    one compiled span, so spans start inside windows), equal to the Python loop's."""
    params, effects = CASES["every online state, μ(T), lag"]
    ssm = _space(params, effects, True)
    loop, fused = _filters(ssm)
    x0, P0 = ssm.prior(ssm.model.initial_state(30.0), 5.0)
    y = _readings(ssm)
    whole = urts_smooth(loop.run(x0, P0, y, store="smoother"), store="diag")
    windowed = urts_smooth_windowed(fused, x0, P0, y, window=300, workers=2)
    assert len(windowed.windows) == 3
    np.testing.assert_allclose(windowed.smoothed.x_smooth, whole.x_smooth, atol=1e-6)


def test_a_power_shape_model_on_one_layer() -> None:
    """The paper's one-layer model with a radial power shape (no crown weights)."""
    model = DiscFEModel(load_disc(), 12, 1, power_shape=lambda r: r**2)
    q = np.where(np.arange(K) % 60 < 15, 50e3, 0.0)
    ssm = DiscStateSpace(model, q, np.full(K, 25.0), np.full(K, 90.0),
                         [RandomWalkParam(SCALE_PARAM, *INIT[SCALE_PARAM][:3])],
                         sigma_temp=0.5, sigma_crown=0.0)
    loop, fused = _filters(ssm)
    x0, P0 = ssm.prior(model.initial_state(30.0), 5.0)
    y = _readings(ssm)
    np.testing.assert_allclose(fused.run(x0, P0, y).x_filt, loop.run(x0, P0, y).x_filt,
                               rtol=1e-10, atol=1e-9)


def test_a_run_past_the_inputs_is_refused() -> None:
    """The compiled loop reads its inputs unchecked: a filter longer than the state
    space's inputs must not read past them."""
    ssm = _space((SCALE_PARAM,), DiscEffects(), True)
    _, fused = _filters(ssm)
    x0, P0 = ssm.prior(ssm.model.initial_state(30.0), 5.0)
    y = np.vstack([_readings(ssm)] * 2)
    with pytest.raises(ValueError, match=f"compiled steps up to .* of {K}"):
        fused.run(x0, P0, y)
    X0 = np.tile(x0, (3, 1))
    with pytest.raises(ValueError, match=f"of {K}"):
        ssm.replay(X0, np.zeros((10, 3, ssm.n)), K - 5)
    with pytest.raises(ValueError, match="corrections of shape"):
        ssm.replay(X0, np.zeros((10, 2, ssm.n)))


def test_a_cancelled_speculative_run_stops() -> None:
    """The estimate's guess stops on request on the compiled path too."""
    import threading

    from brakethermo.pipelines.speculative import Cancelled, cancellable, cancellable_steps

    ssm = _space((SCALE_PARAM,), DiscEffects(), True)
    cancel = threading.Event()
    cancel.set()
    ukf = UnscentedKalmanFilter(cancellable(ssm.f, cancel), ssm.Q, np.array([[4.0]]),
                                H=ssm.H_measured(0.15),
                                steps=cancellable_steps(ssm.compiled_steps(), cancel))
    x0, P0 = ssm.prior(ssm.model.initial_state(30.0), 5.0)
    with pytest.raises(Cancelled):
        ukf.run(x0, P0, _readings(ssm))


def test_a_breakdown_names_the_time_span() -> None:
    ssm = _space((SCALE_PARAM,), DiscEffects(), True)
    y = _readings(ssm)
    ssm.model._kernel_args = (*ssm.model._kernel_args[:2], 0.0, *ssm.model._kernel_args[3:])
    _, fused = _filters(ssm)
    x0, P0 = ssm.prior(ssm.model.initial_state(30.0), 5.0)
    with pytest.raises(DataError, match=r"broke down between t = 0\.0 and"):
        fused.run(x0, P0, y)


@pytest.mark.parametrize("case", list(CASES))
def test_compiled_replay_equals_the_python_loop(case: str) -> None:
    """whatif's replay: members with their own inputs per step, a correction after each."""
    params, effects = CASES[case]
    base = _space(params, effects, True)
    S, k0, steps = 3, 50, 120
    g = np.array([1.0, 0.8, 1.3])
    h = None if H_PARAM in params else base.h[:, None] * g
    ssm = DiscStateSpace(base.model, base.q_brk, np.repeat(base.t_amb[:, None], S, 1), h,
                         base.params, sigma_temp=0.0, sigma_crown=0.0, effects=effects,
                         spot_radius=0.15)
    x0, _ = ssm.prior(ssm.model.initial_state(300.0), 1.0)
    w = np.random.default_rng(5).normal(0.0, 0.3, (steps, S, ssm.n))
    got = ssm.replay(np.tile(x0, (S, 1)), w, k0)
    want = [np.tile(x0, (S, 1))]
    for k in range(steps):
        want.append(ssm.f(want[-1], k0 + k) + w[k])
    np.testing.assert_allclose(got, np.stack(want), rtol=1e-11, atol=1e-9)
    assert np.ptp(got[-1, :, 0]) > 0.5 or h is None  # the members' own h do tell
