"""The roller-rig model: compiled RK4 vs the vectorised reference, a conservation law,
and the joint UKF on it against filterpy's UnscentedKalmanFilter."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints
from filterpy.kalman import UnscentedKalmanFilter as FilterpyUKF

from brakethermo.errors import ConfigError
from brakethermo.estimation import UnscentedKalmanFilter
from brakethermo.models.roller_rig import CreepEffects, RollerRigModel
from brakethermo.rigs.roller_rig import Bearings, load_roller_rig

SPEC = load_roller_rig()


def _inputs(K: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(K) * 0.005
    torque = 400.0 * np.clip(np.sin(2 * np.pi * t / 2.0), 0, None)
    normal = 13e3 * (1 + 0.01 * rng.standard_normal(K))
    return torque, normal, np.full(K, 7.5)


@pytest.mark.parametrize("law", ["polach", "fastsim"])
@pytest.mark.parametrize("effects", [None, CreepEffects(-0.2, 0.3, 2e-4)])
def test_compiled_kernel_equals_vectorised_numpy(law: str, effects: CreepEffects | None) -> None:
    """All sigma points in one compiled call == the numpy RK4 of the same equations."""
    model = RollerRigModel.from_spec(SPEC, creep_law=law, effects=effects)
    torque, normal, supply = _inputs(8)
    f = model.transition(0.005, torque, normal, supply)
    X = np.array([[12.16, 9.36, 0.3482], [12.3, 9.3, 0.32], [12.0, 9.45, 0.40],
                  [-0.1, 0.05, 0.35]])  # fmt: skip
    for k in (0, 3, 7):
        ref = model.propagate_numpy(X, 0.005, (torque[k], torque[min(k + 1, 7)]),
                                    (normal[k], normal[min(k + 1, 7)]), 7.5)  # fmt: skip
        np.testing.assert_allclose(f(X, k), ref, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("law", ["polach", "fastsim"])
def test_carried_creep_effects_are_the_diagnosis_transforms(law: str) -> None:
    """F(xi) = (1 + m) f((1 + a)(xi - d) / (1 + m)), f the datasheet's law: the forms
    ``diagnose`` fits (models.rig_effects.ROLLER_EFFECTS), each alone and together; up
    to the slip velocity, which the diagnosis's curve takes at the shifted wheel speed
    (below 1e-4 of the force at 6e-3 creepage)."""
    plain = RollerRigModel.from_spec(SPEC, creep_law=law)
    w_r = np.full(7, 9.36)
    normal = np.full(7, 13e3)
    r_w = np.full(7, 0.3482)
    xi = np.array([-4e-3, -1e-3, -1e-4, 0.0, 2e-4, 1.5e-3, 6e-3])
    v_r = w_r * SPEC.roller_radius

    def at(x: np.ndarray) -> np.ndarray:  # the wheel speed giving creepage x
        return v_r * (1.0 + 0.5 * x) / (1.0 - 0.5 * x) / r_w

    for a, m, d in ((-0.2, 0.0, 0.0), (0.0, 0.3, 0.0), (0.0, 0.0, 3e-4), (0.4, -0.25, -2e-4)):
        model = RollerRigModel.from_spec(SPEC, creep_law=law, effects=CreepEffects(a, m, d))
        s_x, F = model.creep(at(xi), w_r, r_w, normal)
        np.testing.assert_allclose(s_x, xi, rtol=1e-12, atol=1e-15)
        expect = (1 + m) * plain.creep(at((1 + a) * (xi - d) / (1 + m)), w_r, r_w, normal)[1]
        np.testing.assert_allclose(F, expect, rtol=1e-4, atol=1e-6)
    with pytest.raises(ConfigError, match="out of range"):
        CreepEffects(slope_change=-1.2)


def test_contact_force_cancels_in_the_angular_impulse() -> None:
    """Without motor and bearings, J_w w_w / r_w + J_r w_r / R_r grows by int T_P / r_w dt.

    The contact force acts on both bodies with opposite signs (paper eq. 10); whatever
    the creep law, it cancels in this sum, which RK4 then integrates exactly for a
    torque linear in time.
    """
    quiet = dataclasses.replace(
        SPEC, bearings=Bearings(0.0, 0.0, 0.0, 0.0),
        motor=dataclasses.replace(SPEC.motor, v_th=0.0),
    )  # fmt: skip
    model = RollerRigModel.from_spec(quiet)
    K = 400
    torque, normal, supply = _inputs(K)
    f = model.transition(0.005, torque, normal, supply)
    x = np.array([[12.0, 9.3, 0.3482]])
    r, R = 0.3482, SPEC.roller_radius

    def impulse(x: np.ndarray) -> float:
        return SPEC.wheel_inertia * x[0, 0] / r + SPEC.roller_inertia * x[0, 1] / R

    p0 = impulse(x)
    for k in range(K - 1):
        x = f(x, k)
    expected = p0 + np.sum(0.5 * (torque[:-1] + torque[1:])) * 0.005 / r
    assert impulse(x) == pytest.approx(expected, rel=1e-10)
    assert x[0, 2] == 0.3482  # the radius is a parameter: carried unchanged


def test_substep_and_creep_law_are_checked() -> None:
    with pytest.raises(ConfigError, match="substep"):
        RollerRigModel.from_spec(SPEC, substep=0.02)
    with pytest.raises(ConfigError, match="creep law"):
        RollerRigModel.from_spec(SPEC, creep_law="coulomb")


def _session(K: int, seed: int) -> tuple:
    """Speeds from the model itself with the paper's noise, for the cross-check."""
    model = RollerRigModel.from_spec(SPEC)
    torque, normal, supply = _inputs(K, seed)
    f = model.transition(0.005, torque, normal, supply)
    rng = np.random.default_rng(seed)
    x = np.array([[12.16, 9.36, 0.3482]])
    y = np.empty((K, 2))
    for k in range(K):
        y[k] = x[0, :2] + rng.normal(0, 0.01, 2)
        if k < K - 1:
            x = f(x, k)
    return f, y


@pytest.mark.parametrize(("alpha", "kappa", "q_r"), [(1.0, 0.0, 1e-11), (0.5, 1.0, 1e-9)])
def test_joint_ukf_matches_filterpy_on_the_same_model(alpha: float, kappa: float, q_r: float):
    """Our UKF (one batched model call per step) vs filterpy (one call per sigma point)."""
    K = 300
    f, y = _session(K, 5)
    Q = np.diag([1e-4, 1e-4, q_r])
    R = np.diag([1e-4, 1e-4])
    H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    x0, P0 = np.array([y[0, 0], y[0, 1], 0.34]), np.diag([1e-1, 1e-1, 1e-4])
    ours = UnscentedKalmanFilter(f, Q, R, H=H, alpha=alpha, beta=2.0, kappa=kappa).run(x0, P0, y)
    pts = MerweScaledSigmaPoints(3, alpha=alpha, beta=2.0, kappa=kappa)
    fp = FilterpyUKF(dim_x=3, dim_z=2, dt=0.005, hx=lambda x: H @ x,
                     fx=lambda x, dt, k: f(x[None], k)[0], points=pts)  # fmt: skip
    fp.x, fp.P, fp.Q, fp.R = x0.copy(), P0.copy(), Q, R
    fp.sigmas_f = pts.sigma_points(fp.x, fp.P)
    xs, Ps = np.empty((K, 3)), np.empty((K, 3, 3))
    for k in range(K):
        if k > 0:
            fp.predict(k=k - 1)
        fp.update(y[k])
        xs[k], Ps[k] = fp.x, fp.P
    np.testing.assert_allclose(ours.x_filt, xs, rtol=0, atol=1e-8)
    np.testing.assert_allclose(ours.var_filt, np.diagonal(Ps, axis1=1, axis2=2), rtol=1e-6,
                               atol=1e-14)  # fmt: skip
    assert abs(ours.x_filt[-1, 2] - 0.3482) < 2e-3
