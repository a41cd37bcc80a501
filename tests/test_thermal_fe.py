"""Disc FE model against analytic solutions and its own conservation laws."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import i0, i1, k0, k1

from brakethermo.thermal.disc import DiscSpec, load_disc
from brakethermo.thermal.fe import nodal_areas
from brakethermo.thermal.model import DiscFEModel

K_CONST = 40.0  # W/(m K)
C_CONST = 1200.0  # J/(kg K)
_MODEL_L2 = DiscFEModel(load_disc("cc-340-8"), 13, 2, kz_ratio=0.3)


@pytest.fixture(scope="module")
def disc() -> DiscSpec:
    return load_disc("cc-340-8")


@pytest.fixture(scope="module")
def linear_disc(disc: DiscSpec) -> DiscSpec:
    """Constant c and k, no radiation: the model is linear."""
    return dataclasses.replace(
        disc,
        c_temp_c=(0.0,),
        c_value=(C_CONST,),
        k_temp_c=(0.0,),
        k_value=(K_CONST,),
        emissivity=0.0,
    )


def fin_solution(spec: DiscSpec, h: float, q: float, weights: np.ndarray, r: np.ndarray):
    """Steady annular fin, Robin rims, crown heat source: theta = T - T_amb (K).

    k s (1/r)(r theta')' - 2 h theta + f(r) = 0; in each piece of constant flux f,
    theta = A I0(m r) + B K0(m r) + f / (2 h), m^2 = 2 h / (k s); theta and theta'
    continuous at the crown edges; k theta' = h theta at r_int, -k theta' = h theta at r_est.
    """
    k, s = K_CONST, spec.thickness
    m = np.sqrt(2.0 * h / (k * s))
    crowns = spec.crown_edges
    edges = np.concatenate(([spec.r_int], crowns))
    edges = edges[np.concatenate(([True], np.diff(edges) > 0))]
    w = weights * np.pi * np.diff(crowns**2).sum() / np.dot(np.pi * np.diff(crowns**2), weights)
    f_crown = w * q / (np.pi * (crowns[-1] ** 2 - crowns[0] ** 2))
    f = np.concatenate((np.zeros(edges.size - 1 - 3), f_crown))
    P = f.size
    A = np.zeros((2 * P, 2 * P))
    rhs = np.zeros(2 * P)

    def val(x: float) -> np.ndarray:
        return np.array([i0(m * x), k0(m * x)])

    def der(x: float) -> np.ndarray:
        return m * np.array([i1(m * x), -k1(m * x)])

    A[0, 0:2] = k * der(edges[0]) - h * val(edges[0])
    rhs[0] = h * f[0] / (2 * h)
    for j in range(P - 1):
        x = edges[j + 1]
        A[1 + 2 * j, 2 * j : 2 * j + 2] = val(x)
        A[1 + 2 * j, 2 * j + 2 : 2 * j + 4] = -val(x)
        rhs[1 + 2 * j] = (f[j + 1] - f[j]) / (2 * h)
        A[2 + 2 * j, 2 * j : 2 * j + 2] = der(x)
        A[2 + 2 * j, 2 * j + 2 : 2 * j + 4] = -der(x)
    A[-1, -2:] = -k * der(edges[-1]) - h * val(edges[-1])
    rhs[-1] = h * f[-1] / (2 * h)
    coef = np.linalg.solve(A, rhs)
    piece = np.clip(np.searchsorted(edges, r, side="right") - 1, 0, P - 1)
    ab = coef.reshape(P, 2)[piece]
    return ab[:, 0] * i0(m * r) + ab[:, 1] * k0(m * r) + f[piece] / (2 * h)


@pytest.mark.parametrize("weights", [(1.0, 1.0, 1.0), (0.5, 1.3, 0.9)])
def test_steady_annular_fin_converges_second_order(linear_disc: DiscSpec, weights) -> None:
    h, q, t_amb = 80.0, 20.0e3, 25.0
    errors = []
    sizes = (11, 21, 41, 81)
    for n in sizes:
        model = DiscFEModel(linear_disc, n, weights=weights, dt=1.0e12)
        T = model.step(model.initial_state(t_amb), q, h, t_amb)
        exact = fin_solution(linear_disc, h, q, np.asarray(weights), model.radii)
        errors.append(np.max(np.abs(T - t_amb - exact)) / np.max(exact))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] < 2e-4
    assert np.all(orders > 1.7), (errors, orders)


def test_steady_fin_with_inner_rim_heat_flux(linear_disc: DiscSpec) -> None:
    """Heat Q enters through the inner rim (all of it at node 0), faces and rims convect.

    -k theta'(r_i) 2 pi r_i s = Q - h theta(r_i) 2 pi r_i s, -k theta'(r_e) = h theta(r_e);
    theta = A I0(m r) + B K0(m r).
    """
    h, q, t_amb = 60.0, 3.0e3, 20.0
    spec = linear_disc
    k, s, r_i, r_e = K_CONST, spec.thickness, spec.r_int, spec.r_est
    m = np.sqrt(2.0 * h / (k * s))
    rim = 2.0 * np.pi * r_i * s
    A = np.array(
        [
            [-k * m * i1(m * r_i) * rim + h * i0(m * r_i) * rim,
             k * m * k1(m * r_i) * rim + h * k0(m * r_i) * rim],
            [-k * m * i1(m * r_e) - h * i0(m * r_e), k * m * k1(m * r_e) - h * k0(m * r_e)],
        ]
    )  # fmt: skip
    coef = np.linalg.solve(A, [q, 0.0])
    errors = []
    for n in (11, 21, 41, 81):
        model = DiscFEModel(spec, n, dt=1.0e12)
        rim_load = np.zeros(n)
        rim_load[0] = 1.0
        T = model.step(model.initial_state(t_amb), q, h, t_amb, load=rim_load)
        exact = coef[0] * i0(m * model.radii) + coef[1] * k0(m * model.radii)
        errors.append(np.max(np.abs(T - t_amb - exact)) / np.max(exact))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] < 1e-4
    assert np.all(orders > 1.8), (errors, orders)


def test_lumped_cooling_matches_exponential(linear_disc: DiscSpec) -> None:
    spec = dataclasses.replace(linear_disc, k_value=(1.0e7,))  # Biot -> 0: uniform T
    h, t_amb, theta0, t_end = 60.0, 20.0, 400.0, 60.0
    r_i, r_e, s = spec.r_int, spec.r_est, spec.thickness
    area = 2 * np.pi * (r_e**2 - r_i**2) + 2 * np.pi * (r_i + r_e) * s
    C = spec.density * C_CONST * np.pi * (r_e**2 - r_i**2) * s
    lam = h * area / C
    errors = []
    for dt in (0.4, 0.2, 0.1):
        model = DiscFEModel(spec, 12, dt=dt)
        K = round(t_end / dt)
        T = model.open_loop(model.initial_state(t_amb + theta0), np.zeros(K), h, t_amb)
        theta = T[:, 0] - t_amb
        discrete = theta0 / (1.0 + lam * dt) ** np.arange(K + 1)  # backward Euler
        np.testing.assert_allclose(theta, discrete, rtol=1e-6)
        assert np.ptp(T[-1]) < 1e-4 * theta0
        errors.append(abs(theta[-1] - theta0 * np.exp(-lam * t_end)))
    # backward Euler is first order in dt
    np.testing.assert_allclose(np.array(errors[:-1]) / np.array(errors[1:]), 2.0, rtol=0.1)


def assert_energy_conserved(model: DiscFEModel, seed: int) -> None:
    """Stored heat of each step equals dt x (friction - convection - radiation)."""
    rng = np.random.default_rng(seed)
    B = 6
    T = 200.0 + 150.0 * rng.random((B, model.n_state))
    h = rng.uniform(30.0, 150.0, B)
    scale = rng.uniform(0.7, 1.3, B)
    for q in (0.0, 45.0e3, 80.0e3):
        T_new = model.step(T, q, h, 28.0, scale)
        stored = (model.capacity(T) * (T_new - T)).sum(axis=1)
        terms = model.power_terms(T, T_new, q, h, 28.0, scale)
        np.testing.assert_allclose(terms.friction, q * scale, rtol=1e-13)
        np.testing.assert_allclose(stored, model.dt * terms.net, rtol=1e-10, atol=1e-7)
        T = T_new


@pytest.mark.parametrize("layers", [1, 3])
def test_energy_conserved_per_step(disc: DiscSpec, layers: int) -> None:
    model = DiscFEModel(disc, 17, layers, weights=(0.7, 1.2, 1.0), kz_ratio=0.4)
    assert_energy_conserved(model, seed=3)


def test_energy_function_is_exact_enthalpy(disc: DiscSpec, linear_disc: DiscSpec) -> None:
    model = DiscFEModel(linear_disc, 10)
    T = np.random.default_rng(4).uniform(20.0, 600.0, (3, model.n_state))
    T_new = model.step(T, 3.0e4, 70.0, 20.0)
    terms = model.power_terms(T, T_new, 3.0e4, 70.0, 20.0)
    np.testing.assert_allclose(model.energy(T_new) - model.energy(T), model.dt * terms.net)
    # variable c: energy = sum rho V int_0^T c dT, checked by quadrature
    full = DiscFEModel(disc, 10)
    t = np.linspace(0.0, 1200.0, 200_001)
    mass = disc.density * np.pi * (disc.r_est**2 - disc.r_int**2) * disc.thickness
    e = np.trapezoid(disc.specific_heat(t), t) * mass
    assert full.energy(full.initial_state(1200.0)) == pytest.approx(e, rel=1e-9)
    assert full.energy(full.initial_state(-20.0)) == pytest.approx(-20.0 * 700.0 * mass)


def test_braking_heats_and_radiation_cools(disc: DiscSpec) -> None:
    model = DiscFEModel(disc, 10)
    T0 = model.initial_state(500.0)
    hot = model.step(T0, 8.0e4, 80.0, 25.0)
    assert np.all(hot[model.radii > disc.pad_r1 + 0.01] > 500.0)
    no_h = model.step(T0, 0.0, 0.0, 25.0)
    assert np.all(no_h < 500.0)  # radiation alone cools a hot disc
    assert np.all(no_h > 499.0)


def test_layers_with_huge_kz_equal_one_layer(disc: DiscSpec) -> None:
    one = DiscFEModel(disc, 12, 1)
    many = DiscFEModel(disc, 12, 4, kz_ratio=1.0e5)
    q = np.where(np.arange(300) % 100 < 30, 7.0e4, 0.0)
    a = one.open_loop(one.initial_state(150.0), q, 90.0, 25.0)
    b = many.open_loop(many.initial_state(150.0), q, 90.0, 25.0)
    np.testing.assert_allclose(b[:, many.face_index], a, atol=0.05)
    layers = b.reshape(-1, 12, 4)
    assert np.max(np.ptp(layers, axis=2)) < 0.05


def test_low_kz_face_runs_hotter_than_midplane(disc: DiscSpec) -> None:
    model = DiscFEModel(disc, 12, 3, kz_ratio=0.05)
    T = model.open_loop(model.initial_state(150.0), np.full(30, 7.0e4), 90.0, 25.0)
    layers = T[-1].reshape(12, 3)
    contact = model.radii > disc.pad_r1 + 0.005
    assert np.all(layers[contact, 0] > layers[contact, 2] + 5.0)
    # and the default ratio gives a smaller but positive through-thickness gradient
    stiff = DiscFEModel(disc, 12, 3)
    Ts = stiff.open_loop(stiff.initial_state(150.0), np.full(30, 7.0e4), 90.0, 25.0)
    gap = Ts[-1].reshape(12, 3)[contact]
    assert np.all(gap[:, 0] > gap[:, 2])
    assert np.all(gap[:, 0] - gap[:, 2] < layers[contact, 0] - layers[contact, 2])


# (150, 4): 1201 members in blocks that keep a 600-node mesh's work arrays in cache
@pytest.mark.parametrize(("n", "layers"), [(10, 1), (23, 2), (15, 3), (15, 6), (150, 4)])
def test_numba_step_equals_numpy_step(disc: DiscSpec, n: int, layers: int) -> None:
    fast = DiscFEModel(disc, n, layers, use_numba=True)
    slow = DiscFEModel(disc, n, layers, use_numba=False)
    rng = np.random.default_rng(n)
    B = 2 * fast.n_state + 1
    T = rng.uniform(-10.0, 1100.0, (B, fast.n_state))  # beyond both table ends
    args = (6.0e4, rng.uniform(20, 200, B), rng.uniform(0, 40, B), rng.uniform(0.5, 1.5, B))
    kz = rng.uniform(0.05, 3.0, B)
    np.testing.assert_allclose(
        fast.step(T, *args, kz_ratio=kz), slow.step(T, *args, kz_ratio=kz), rtol=1e-12, atol=1e-9
    )


def test_shared_matrix_is_exact_for_linear_model(linear_disc: DiscSpec, disc: DiscSpec) -> None:
    model = DiscFEModel(linear_disc, 14, 2)
    T = np.random.default_rng(5).uniform(50, 500, (9, model.n_state))
    own = model.step(T, 5.0e4, 80.0, 20.0, np.linspace(0.8, 1.2, 9))
    shared = model.step(T, 5.0e4, 80.0, 20.0, np.linspace(0.8, 1.2, 9), shared_matrix_from=T[0])
    np.testing.assert_allclose(shared, own, rtol=1e-12)
    nonlinear = DiscFEModel(disc, 14, 2)
    ref = T.mean(axis=0)
    one = nonlinear.step(ref, 5.0e4, 80.0, 20.0, shared_matrix_from=ref)
    np.testing.assert_allclose(one, nonlinear.step(ref, 5.0e4, 80.0, 20.0), rtol=1e-12)
    with pytest.raises(ValueError, match="one h"):
        nonlinear.step(T, 0.0, np.linspace(50, 90, 9), 20.0, shared_matrix_from=ref)


def test_single_state_and_open_loop_agree(disc: DiscSpec) -> None:
    model = DiscFEModel(disc, 10, 2)
    T0 = model.initial_state(200.0)
    q = np.array([5.0e4, 0.0, 2.0e4])
    path = model.open_loop(T0, q, 70.0, 22.0)
    assert path.shape == (4, model.n_state)
    T = T0
    for k in range(3):
        T = model.step(T, q[k], 70.0, 22.0)
        assert T.shape == (model.n_state,)
        np.testing.assert_array_equal(path[k + 1], T)
    with pytest.raises(ValueError, match="shape"):
        model.step(np.zeros((2, 3)), 0.0, 70.0, 22.0)


def test_spot_matrix_interpolates_face_nodes(disc: DiscSpec) -> None:
    model = DiscFEModel(disc, 10, 3)
    H = model.spot_matrix(disc.spot_radii)
    assert H.shape == (4, model.n_state)
    np.testing.assert_allclose(H.sum(axis=1), 1.0)
    assert np.count_nonzero(H, axis=1).max() <= 2
    assert set(np.nonzero(H)[1]) <= set(model.face_index)
    T = np.zeros(model.n_state)
    T[model.face_index] = 3.0 + 1000.0 * model.radii  # linear in r on the face
    np.testing.assert_allclose(H @ T, 3.0 + 1000.0 * np.array(disc.spot_radii))
    np.testing.assert_allclose(model.spot_matrix([disc.r_int, disc.r_est]) @ T, T[[0, -3]])
    with pytest.raises(ValueError, match="inside"):
        model.spot_matrix([0.05])


@pytest.mark.parametrize("members", [70, 993])
def test_shared_matrix_numba_equals_numpy(disc: DiscSpec, members: int) -> None:
    """More than one kernel block; 993 members leave a last block of one, which took its
    own temperature for the shared matrix (100 K off) until the block read Tm always."""
    fast = DiscFEModel(disc, 150, 4, use_numba=True)
    slow = DiscFEModel(disc, 150, 4, use_numba=False)
    T = np.random.default_rng(6).uniform(50, 900, (members, fast.n_state))
    ref = T.mean(axis=0)
    kw = {"shared_matrix_from": ref, "kz_ratio": 0.5}
    scale = np.linspace(0.9, 1.1, members)
    a = fast.step(T, 4.0e4, 75.0, 18.0, scale, **kw)
    b = slow.step(T, 4.0e4, 75.0, 18.0, scale, **kw)
    np.testing.assert_allclose(a, b, rtol=1e-12)
    assert fast.step(T[:0], 4.0e4, 75.0, 18.0).shape == (0, fast.n_state)


@pytest.mark.parametrize("use_numba", [False, True])
def test_per_member_load_equals_models_with_those_weights(disc: DiscSpec, use_numba) -> None:
    weights = np.array([[1.0, 1.0, 1.0], [0.3, 1.0, 2.0], [2.0, 0.5, 0.1]])
    base = DiscFEModel(disc, 15, 2, use_numba=use_numba)
    areas = np.pi * np.diff(disc.crown_edges**2)
    w = weights * areas.sum() / (weights @ areas)[:, None]  # eq. 8
    rows = w @ base.crown_basis()
    T = np.tile(base.initial_state(200.0), (3, 1))
    batched = base.step(T, 6.0e4, 80.0, 20.0, load=rows)
    for b in range(3):
        own = DiscFEModel(disc, 15, 2, weights=weights[b], use_numba=use_numba)
        np.testing.assert_allclose(own.load, rows[b], rtol=1e-12)
        np.testing.assert_allclose(batched[b], own.step(T[b], 6.0e4, 80.0, 20.0), rtol=1e-12)
    terms = base.power_terms(T, batched, 6.0e4, 80.0, 20.0, load=rows)
    np.testing.assert_allclose(terms.friction, 6.0e4, rtol=1e-12)
    with pytest.raises(ValueError, match="load must have shape"):
        base.step(T, 6.0e4, 80.0, 20.0, load=rows[:2])


def test_constant_kz_overrides_in_plane_table(disc: DiscSpec) -> None:
    q = np.full(20, 7.0e4)
    table = DiscFEModel(disc, 12, 3, kz_ratio=0.2)
    const = DiscFEModel(disc, 12, 3, k_z=0.2 * 40.0)
    gap_table = np.ptp(table.open_loop(table.initial_state(100.0), q, 80.0, 20.0)[-1])
    gap_const = np.ptp(const.open_loop(const.initial_state(100.0), q, 80.0, 20.0)[-1])
    assert gap_const == pytest.approx(gap_table, rel=0.05)  # k(T) ~ 40 W/(m K) near 100 degC
    lower = DiscFEModel(disc, 12, 3, k_z=2.0)
    gap_lower = np.ptp(lower.open_loop(lower.initial_state(100.0), q, 80.0, 20.0)[-1])
    assert gap_lower > gap_const


@settings(max_examples=40, deadline=None)
@given(
    t_amb=st.floats(-10.0, 45.0),
    h=st.floats(0.0, 400.0),
    spread=st.floats(0.0, 900.0),
    seed=st.integers(0, 2**16),
)
def test_cooling_step_obeys_maximum_principle(t_amb, h, spread, seed) -> None:
    """M-matrix (lumped) scheme: without braking no node leaves [T_amb, max T]."""
    model = _MODEL_L2
    T = t_amb + spread * np.random.default_rng(seed).random((4, model.n_state))
    T_new = model.step(T, 0.0, h, t_amb)
    assert np.all(T_new <= T.max(axis=1, keepdims=True) + 1e-9)
    assert np.all(T_new >= t_amb - 1e-9)


def test_surface_temperature_brackets_face_layer(disc: DiscSpec) -> None:
    model = DiscFEModel(disc, 15, 3, kz_ratio=0.3)
    T = model.open_loop(model.initial_state(150.0), np.full(20, 7.0e4), 90.0, 25.0)[-1]
    braking = model.surface_temperature(T, 7.0e4, 90.0, 25.0)
    face = T[model.face_index]
    contact = model.radii > disc.pad_r1 + 0.005
    assert np.all(braking[contact] > face[contact] + 1.0)
    # off the brakes the surface is cooled, so slightly below the face layer
    cooling = model.surface_temperature(T, 0.0, 90.0, 25.0)
    assert np.all(cooling < face)
    assert np.all(cooling > face - 5.0)
    # the jump follows the flux balance: k_z (T_s - T_face) / (s / 4L) = net flux
    k_z = 0.3 * disc.conductivity(face)
    flux_in = k_z * (braking - face) / (disc.thickness / 12.0)
    sig = 5.670374419e-8 * disc.emissivity * ((face + 273.15) ** 4 - (25.0 + 273.15) ** 4)
    friction = 7.0e4 * model.load / (2.0 * nodal_areas(model.radii))
    expected = friction - 90.0 * (braking - 25.0) - sig
    np.testing.assert_allclose(flux_in, expected, rtol=1e-10, atol=1e-6)
