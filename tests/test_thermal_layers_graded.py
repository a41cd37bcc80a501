"""Geometrically graded through-thickness layers of the disc FE model (``layer_growth``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_thermal_fe import assert_energy_conserved

from brakethermo.thermal.disc import DiscSpec, load_disc
from brakethermo.thermal.fe import conduction_factors, nodal_areas
from brakethermo.thermal.model import SIGMA, DiscFEModel, layer_thicknesses

DISC = load_disc("cc-340-8")
NUMBA = [False, True]


def dense_step(
    disc: DiscSpec,
    N: int,
    t: np.ndarray,
    T: np.ndarray,
    q: float,
    h: float,
    t_amb: float,
    kz_ratio: float,
    load: np.ndarray,
    dt: float = 0.1,
) -> np.ndarray:
    """Eq. 15 for one state, assembled densely from per-layer thicknesses ``t`` (both halves).

    Independent of the model's band storage and geometric-factor bookkeeping: capacity
    ``rho a_i t_j c``, radial conductance ``k t_j g_e``, interface conductance through two
    mirrored half-distances ``(t_j + t_{j+1}) / 4``, faces on layer 0, rims on every layer.
    """
    L = t.size
    r = np.linspace(disc.r_int, disc.r_est, N)
    a = nodal_areas(r)
    g = conduction_factors(r)
    T3 = T.reshape(N, L)
    c = np.interp(T3, disc.c_temp_c, disc.c_value)
    k = lambda x: np.interp(x, disc.k_temp_c, disc.k_value)  # noqa: E731
    n = N * L
    A = np.diag((disc.density * a[:, None] * t[None, :] * c / dt).ravel())
    b = A @ T
    idx = np.arange(n).reshape(N, L)

    def couple(p: int, m: int, G: float) -> None:
        A[p, p] += G
        A[m, m] += G
        A[p, m] -= G
        A[m, p] -= G

    for i in range(N):
        for j in range(L):
            if i + 1 < N:
                couple(idx[i, j], idx[i + 1, j], k(0.5 * (T3[i, j] + T3[i + 1, j])) * t[j] * g[i])
            if j + 1 < L:
                k_z = kz_ratio * k(0.5 * (T3[i, j] + T3[i, j + 1]))
                couple(idx[i, j], idx[i, j + 1], 2.0 * k_z * a[i] / ((t[j] + t[j + 1]) / 4.0))
    conv = np.zeros((N, L))
    conv[:, 0] += 2.0 * a
    conv[0, :] += 2.0 * np.pi * r[0] * t
    conv[-1, :] += 2.0 * np.pi * r[-1] * t
    A += np.diag(h * conv.ravel())
    b += h * conv.ravel() * t_amb
    rad = 2.0 * a * SIGMA * disc.emissivity * ((T3[:, 0] + 273.15) ** 4 - (t_amb + 273.15) ** 4)
    b[idx[:, 0]] += q * load - rad
    return np.linalg.solve(A, b)


def pulse_face(model: DiscFEModel, q: np.ndarray) -> np.ndarray:
    """Face-layer temperatures, shape (K + 1, N), of an open-loop run from 400 degC."""
    return model.open_loop(model.initial_state(400.0), q, 80.0, 25.0)[:, model.face_index]


def test_layer_thicknesses_are_geometric_and_fill_the_disc() -> None:
    s = DISC.thickness
    t, n_eq = layer_thicknesses(s, 4, 2.5)
    assert t.sum() == pytest.approx(s, rel=1e-15)
    np.testing.assert_allclose(t[1:] / t[:-1], 2.5, rtol=1e-14)
    np.testing.assert_allclose(n_eq, 2.0 * s / (t[:-1] + t[1:]), rtol=1e-14)
    for L in (1, 3, 7, 49):
        t_eq, n_eq = layer_thicknesses(s, L)
        assert np.all(t_eq == s / L)
        assert np.all(n_eq == L)  # exact: growth 1 is the equal-layer model bit for bit
    with pytest.raises(ValueError, match="layer_growth"):
        DiscFEModel(DISC, 10, 3, layer_growth=0.0)


@pytest.mark.parametrize("use_numba", NUMBA)
@pytest.mark.parametrize(("L", "growth"), [(1, 1.0), (3, 1.0), (4, 1.0), (4, 2.5), (3, 0.6)])
def test_step_equals_dense_reference(L: int, growth: float, use_numba: bool) -> None:
    """growth 1 reproduces the equal-layer scheme (t = s/L, G_z = 4 L a k_z / s); graded too."""
    N = 7
    model = DiscFEModel(DISC, N, L, kz_ratio=0.06, layer_growth=growth, use_numba=use_numba)
    if growth == 1.0:
        t = np.full(L, DISC.thickness / L)
        default = DiscFEModel(DISC, N, L, kz_ratio=0.06, use_numba=use_numba)
    else:
        t = DISC.thickness * growth ** np.arange(L) / np.sum(growth ** np.arange(L))
        default = model
    rng = np.random.default_rng(L)
    T = rng.uniform(-10.0, 1100.0, (3, model.n_state))
    out = model.step(T, 6.0e4, 85.0, 22.0)
    np.testing.assert_array_equal(out, default.step(T, 6.0e4, 85.0, 22.0))
    for b in range(3):
        ref = dense_step(DISC, N, t, T[b], 6.0e4, 85.0, 22.0, 0.06, model.load)
        np.testing.assert_allclose(out[b], ref, rtol=1e-12, atol=1e-10)


@pytest.mark.parametrize("use_numba", NUMBA)
def test_energy_conserved_per_step_graded(use_numba: bool) -> None:
    model = DiscFEModel(
        DISC, 17, 4, weights=(0.7, 1.2, 1.0), kz_ratio=0.06, layer_growth=2.5, use_numba=use_numba
    )
    assert_energy_conserved(model, seed=11)
    # capacity follows each layer's own thickness and the whole disc's volume
    C = model.capacity(model.initial_state(300.0)).reshape(17, 4)
    mass = DISC.density * np.pi * (DISC.r_est**2 - DISC.r_int**2) * DISC.thickness
    assert C.sum() == pytest.approx(mass * np.interp(300.0, DISC.c_temp_c, DISC.c_value))
    np.testing.assert_allclose(C[:, 1:] / C[:, :-1], 2.5, rtol=1e-13)


@pytest.mark.parametrize(("n", "layers", "growth"), [(10, 4, 2.5), (23, 2, 3.0), (15, 6, 1.7)])
def test_numba_equals_numpy_graded(n: int, layers: int, growth: float) -> None:
    fast = DiscFEModel(DISC, n, layers, layer_growth=growth, use_numba=True)
    slow = DiscFEModel(DISC, n, layers, layer_growth=growth, use_numba=False)
    rng = np.random.default_rng(n)
    B = 2 * fast.n_state + 1  # more than one kernel block
    T = rng.uniform(-10.0, 1100.0, (B, fast.n_state))
    args = (6.0e4, rng.uniform(20, 200, B), rng.uniform(0, 40, B), rng.uniform(0.5, 1.5, B))
    kz = rng.uniform(0.05, 3.0, B)
    np.testing.assert_allclose(
        fast.step(T, *args, kz_ratio=kz), slow.step(T, *args, kz_ratio=kz), rtol=1e-12, atol=1e-9
    )
    kw = {"shared_matrix_from": T.mean(axis=0), "kz_ratio": 0.3}
    np.testing.assert_allclose(
        fast.step(T, 6.0e4, 80.0, 20.0, **kw), slow.step(T, 6.0e4, 80.0, 20.0, **kw), rtol=1e-12
    )


@settings(max_examples=30, deadline=None)
@given(
    layers=st.integers(1, 6),
    growth=st.floats(0.3, 4.0),
    t_c=st.floats(-10.0, 900.0),
    h=st.floats(0.0, 300.0),
    kz_ratio=st.floats(0.02, 2.0),
)
def test_uniform_state_without_braking_stays_uniform(
    layers: int, growth: float, t_c: float, h: float, kz_ratio: float
) -> None:
    """At ambient nothing flows; adiabatic and dark, any uniform temperature is steady."""
    model = DiscFEModel(DISC, 9, layers, kz_ratio=kz_ratio, layer_growth=growth)
    T = model.step(model.initial_state(t_c), 0.0, h, t_c)
    np.testing.assert_allclose(T, t_c, rtol=1e-13, atol=1e-10)
    dark = DiscFEModel(
        dataclasses.replace(DISC, emissivity=0.0), 9, layers, kz_ratio=kz_ratio,
        layer_growth=growth,
    )  # fmt: skip
    T = dark.step(dark.initial_state(t_c), 0.0, 0.0, 25.0)
    np.testing.assert_allclose(T, t_c, rtol=1e-13, atol=1e-10)


def test_graded_face_layer_converges_to_fine_model() -> None:
    """Under a braking pulse with a poorly conducting weave the face of a graded 4-layer
    model tracks a fine 40-layer one better than 4 equal layers do."""
    q = np.concatenate((np.full(30, 6.0e4), np.zeros(100)))  # 3 s braking, 10 s cooling
    kw = {"kz_ratio": 0.06}
    fine = pulse_face(DiscFEModel(DISC, 10, 40, **kw), q)
    equal = pulse_face(DiscFEModel(DISC, 10, 4, **kw), q)
    graded = pulse_face(DiscFEModel(DISC, 10, 4, layer_growth=2.5, **kw), q)
    contact = slice(3, None)  # radii under the pads
    err_equal = np.max(np.abs(equal - fine)[:, contact])
    err_graded = np.max(np.abs(graded - fine)[:, contact])
    assert err_equal > 10.0  # the hot skin is real: equal layers smear it
    assert err_graded < 0.5 * err_equal, (err_graded, err_equal)


def test_surface_jump_uses_the_face_layer_half_depth() -> None:
    model = DiscFEModel(DISC, 15, 4, kz_ratio=0.3, layer_growth=2.5)
    T = model.open_loop(model.initial_state(150.0), np.full(20, 7.0e4), 90.0, 25.0)[-1]
    braking = model.surface_temperature(T, 7.0e4, 90.0, 25.0)
    face = T[model.face_index]
    k_z = 0.3 * DISC.conductivity(face)
    flux_in = k_z * (braking - face) / (model.layer_thickness[0] / 4.0)
    sig = SIGMA * DISC.emissivity * ((face + 273.15) ** 4 - (25.0 + 273.15) ** 4)
    friction = 7.0e4 * model.load / (2.0 * nodal_areas(model.radii))
    expected = friction - 90.0 * (braking - 25.0) - sig
    np.testing.assert_allclose(flux_in, expected, rtol=1e-10, atol=1e-6)
