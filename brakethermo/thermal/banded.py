"""Batched solves of symmetric positive-definite banded systems (LDL^T, no pivoting).

The disc model's system matrix ``M/dt + A_cond + A_conv`` (eq. 15) is symmetric, and
diagonally dominant with positive diagonal (an M-matrix), so an LDL^T factorisation
without pivoting is stable and needs no square roots. Every member of a batch (one per
sigma point) has its own matrix; the kernels loop over the batch in compiled code
(numba) or over the rows with numpy operations vectorised across the batch.

Storage is LAPACK's lower band form, as in :func:`scipy.linalg.solveh_banded` with
``lower=True``: ``ab[b, o, i] = A_b[i + o, i]`` for ``o = 0..p`` (``p`` = half-bandwidth);
entries with ``i + o >= n`` are ignored.
"""

from __future__ import annotations

import numba
import numpy as np


def _factor_numpy(ab: np.ndarray) -> None:
    """In-place right-looking banded LDL^T: diagonal <- D, sub-diagonals <- L."""
    p = ab.shape[1] - 1
    n = ab.shape[2]
    for j in range(n):
        d = ab[:, 0, j]
        m = min(p, n - 1 - j)
        for o1 in range(1, m + 1):
            a1 = ab[:, o1, j]
            for o2 in range(o1, m + 1):
                ab[:, o2 - o1, j + o1] -= ab[:, o2, j] * a1 / d
        for o in range(1, m + 1):
            ab[:, o, j] /= d


def _solve_numpy(fac: np.ndarray, x: np.ndarray) -> None:
    """In-place solve with a factor from :func:`_factor_numpy`; ``fac`` batch 1 or B."""
    p = fac.shape[1] - 1
    n = fac.shape[2]
    for j in range(n):
        for o in range(1, min(p, n - 1 - j) + 1):
            x[:, j + o] -= fac[:, o, j] * x[:, j]
    x /= fac[:, 0, :]
    for j in range(n - 2, -1, -1):
        for o in range(1, min(p, n - 1 - j) + 1):
            x[:, j] -= fac[:, o, j] * x[:, j + o]


@numba.njit(cache=True, nogil=True)
def _factor_nb(ab: np.ndarray) -> None:  # pragma: no cover - compiled
    nb, p1, n = ab.shape
    p = p1 - 1
    for b in range(nb):
        for j in range(n):
            d = ab[b, 0, j]
            m = min(p, n - 1 - j)
            for o1 in range(1, m + 1):
                a1 = ab[b, o1, j] / d
                for o2 in range(o1, m + 1):
                    ab[b, o2 - o1, j + o1] -= ab[b, o2, j] * a1
            for o in range(1, m + 1):
                ab[b, o, j] /= d


@numba.njit(cache=True, nogil=True)
def _solve_nb(fac: np.ndarray, x: np.ndarray) -> None:  # pragma: no cover - compiled
    nf, p1, n = fac.shape
    p = p1 - 1
    for b in range(x.shape[0]):
        f = 0 if nf == 1 else b
        for j in range(n):
            xj = x[b, j]
            for o in range(1, min(p, n - 1 - j) + 1):
                x[b, j + o] -= fac[f, o, j] * xj
        for j in range(n):
            x[b, j] /= fac[f, 0, j]
        for j in range(n - 2, -1, -1):
            acc = x[b, j]
            for o in range(1, min(p, n - 1 - j) + 1):
                acc -= fac[f, o, j] * x[b, j + o]
            x[b, j] = acc


def _resolve(use_numba: bool | None) -> bool:
    return True if use_numba is None else use_numba


def factor_banded(ab: np.ndarray, *, use_numba: bool | None = None) -> np.ndarray:
    """LDL^T-factorise a batch of symmetric banded matrices in place.

    Parameters
    ----------
    ab : ndarray, shape (B, p + 1, n)
        Lower band storage (module docstring), float64, C-contiguous; overwritten by
        the factor (D on row 0, unit-lower L on rows 1..p).
    use_numba : bool or None
        ``None`` picks numba.

    Returns
    -------
    ndarray
        ``ab`` itself, now holding the factor.
    """
    if _resolve(use_numba):
        _factor_nb(ab)
    else:
        _factor_numpy(ab)
    return ab


def solve_factored(
    fac: np.ndarray, rhs: np.ndarray, *, use_numba: bool | None = None
) -> np.ndarray:
    """Solve with factors from :func:`factor_banded`.

    Parameters
    ----------
    fac : ndarray, shape (B, p + 1, n) or (1, p + 1, n)
        Factors; a single factor (batch 1) is shared by all right-hand sides.
    rhs : ndarray, shape (B, n)
        Right-hand sides; not modified.

    Returns
    -------
    ndarray, shape (B, n)
    """
    x = np.array(rhs, dtype=np.float64, order="C", copy=True)
    if _resolve(use_numba):
        _solve_nb(fac, x)
    else:
        _solve_numpy(fac, x)
    return x


def solve_banded_batch(
    ab: np.ndarray, rhs: np.ndarray, *, use_numba: bool | None = None, overwrite_ab: bool = False
) -> np.ndarray:
    """Solve ``A_b x_b = rhs_b`` for every batch member ``b``.

    Parameters
    ----------
    ab : ndarray, shape (B, p + 1, n) or (1, p + 1, n)
        Symmetric positive-definite matrices in lower band storage; one matrix (batch 1)
        is factorised once and shared by all right-hand sides.
    rhs : ndarray, shape (B, n)
    use_numba : bool or None
        ``None`` picks numba; ``False`` forces the numpy path.
    overwrite_ab : bool
        Factorise ``ab`` in place instead of a copy.

    Returns
    -------
    ndarray, shape (B, n)
    """
    fac = ab if overwrite_ab else np.array(ab, dtype=np.float64, order="C", copy=True)
    factor_banded(fac, use_numba=use_numba)
    return solve_factored(fac, rhs, use_numba=use_numba)
