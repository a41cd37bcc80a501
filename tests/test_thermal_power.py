"""Pad-crown power distribution (eq. 6–8): power conserved for any weights and mesh."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.thermal.disc import load_disc
from brakethermo.thermal.fe import piecewise_flux_load, radial_nodes
from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.power import crown_areas, crown_load, normalise_weights, shape_load

DISC = load_disc("cc-340-8")
weight = st.floats(min_value=0.0, max_value=50.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(w=st.tuples(weight, weight, weight).filter(lambda w: max(w) > 1e-3),
       n=st.integers(min_value=10, max_value=300))  # fmt: skip
def test_weights_conserve_power(w: tuple[float, float, float], n: int) -> None:
    edges = DISC.crown_edges
    wn = normalise_weights(w, edges)
    total = np.pi * (edges[-1] ** 2 - edges[0] ** 2)
    assert np.dot(crown_areas(edges), wn) == pytest.approx(total, rel=1e-12)  # eq. 8
    b = crown_load(radial_nodes(DISC.r_int, DISC.r_est, n), edges, w)
    assert b.sum() == pytest.approx(1.0, rel=1e-12)
    assert np.all(b >= 0)


@pytest.mark.parametrize("n", [10, 13, 51, 150])
def test_injected_power_is_q_in_the_model(n: int) -> None:
    model = DiscFEModel(DISC, n, weights=(0.2, 1.0, 3.0))
    T = model.initial_state(300.0)
    terms = model.power_terms(T, T, 5.0e4, 0.0, 300.0)
    assert terms.friction[0] == pytest.approx(5.0e4, rel=1e-13)
    # with h = 0 and no radiation exchange at T = T_amb the stored energy rises by Q dt
    T_new = model.step(T, 5.0e4, 0.0, 300.0)
    gained = np.dot(model.capacity(T), T_new - T)
    assert gained == pytest.approx(5.0e4 * model.dt, rel=1e-6)


def test_load_is_exact_integral_against_shape_functions() -> None:
    r = radial_nodes(0.1, 0.17, 9)  # crown edges fall between nodes
    edges = DISC.crown_edges
    values = np.array([1.0, 2.5, 0.5])
    rq = np.linspace(r[0], r[-1], 2_000_001)
    f = np.zeros_like(rq)
    for j in range(3):
        f[(rq >= edges[j]) & (rq < edges[j + 1])] = values[j]
    expected = [np.trapezoid(f * 2 * np.pi * rq * np.interp(rq, r, np.eye(9)[i]), rq)
                for i in range(9)]  # fmt: skip
    np.testing.assert_allclose(piecewise_flux_load(r, edges, values), expected, rtol=1e-5)


def test_arbitrary_shape_matches_crowns_and_is_normalised() -> None:
    r = radial_nodes(DISC.r_int, DISC.r_est, 31)
    edges = DISC.crown_edges
    uniform = shape_load(r, lambda x: ((x >= edges[0]) & (x <= edges[-1])).astype(float), 64)
    assert uniform.sum() == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_allclose(uniform, crown_load(r, edges), atol=2e-3)
    model = DiscFEModel(DISC, 31, power_shape=lambda x: x**2)
    assert model.load.sum() == pytest.approx(1.0)
    assert np.all(np.diff(model.load[1:-1]) > 0)


@pytest.mark.parametrize("bad", [(1.0, 1.0), (0.0, 0.0, 0.0), (1.0, -1.0, 1.0), (np.nan, 1, 1)])
def test_invalid_weights_rejected(bad) -> None:
    with pytest.raises(ValueError, match="weights"):
        normalise_weights(bad, DISC.crown_edges)
