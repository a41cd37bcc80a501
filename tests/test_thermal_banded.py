"""Batched banded LDL^T kernels: numba == numpy fallback == scipy per member."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from brakethermo.thermal.banded import (
    factor_banded,
    solve_banded_batch,
    solve_factored,
)

BACKENDS = [False, True]


def random_spd_band(rng: np.random.Generator, B: int, p: int, n: int) -> np.ndarray:
    """Diagonally dominant symmetric band matrices in lower storage, shape (B, p+1, n)."""
    ab = np.zeros((B, p + 1, n))
    ab[:, 1:, :] = -rng.random((B, p, n))
    for o in range(1, p + 1):
        ab[:, o, n - o :] = 0.0
    row_sum = np.zeros((B, n))
    for o in range(1, p + 1):
        row_sum[:, : n - o] += -ab[:, o, : n - o]
        row_sum[:, o:] += -ab[:, o, : n - o]
    ab[:, 0, :] = row_sum + rng.uniform(0.01, 2.0, (B, n))
    return ab


def scipy_reference(ab: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    return np.stack(
        [scipy.linalg.solveh_banded(ab[min(b, len(ab) - 1)], rhs[b], lower=True)
         for b in range(len(rhs))]
    )  # fmt: skip


@pytest.mark.parametrize("use_numba", BACKENDS)
@pytest.mark.parametrize(("p", "n"), [(1, 2), (1, 150), (2, 30), (3, 60), (4, 9)])
def test_batch_solve_matches_scipy(use_numba: bool, p: int, n: int) -> None:
    rng = np.random.default_rng(100 * p + n)
    ab = random_spd_band(rng, 7, p, n)
    rhs = rng.standard_normal((7, n)) * 1e3
    x = solve_banded_batch(ab, rhs, use_numba=use_numba)
    np.testing.assert_allclose(x, scipy_reference(ab, rhs), rtol=1e-10, atol=1e-10)
    assert np.array_equal(ab, random_spd_band(np.random.default_rng(100 * p + n), 7, p, n))


@pytest.mark.parametrize("use_numba", BACKENDS)
def test_shared_factor_many_rhs(use_numba: bool) -> None:
    rng = np.random.default_rng(1)
    ab = random_spd_band(rng, 1, 2, 40)
    rhs = rng.standard_normal((11, 40))
    fac = factor_banded(ab.copy(), use_numba=use_numba)
    x = solve_factored(fac, rhs, use_numba=use_numba)
    np.testing.assert_allclose(x, scipy_reference(ab, rhs), rtol=1e-10, atol=1e-12)


def test_numba_equals_numpy_fallback() -> None:
    rng = np.random.default_rng(2)
    ab = random_spd_band(rng, 25, 3, 77)
    rhs = rng.standard_normal((25, 77))
    np.testing.assert_allclose(
        solve_banded_batch(ab, rhs, use_numba=True),
        solve_banded_batch(ab, rhs, use_numba=False),
        rtol=1e-13,
        atol=1e-13,
    )
