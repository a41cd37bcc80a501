"""Compiled kernels of the FE disc model (:mod:`brakethermo.thermal.model`): eq. 15's
matrices, right-hand side and banded LDL^T solve fused per batch of members, one step
(``step_nb``) or a whole open-loop run (``run_nb``). Each is tested equal to the numpy
path of :class:`~brakethermo.thermal.model.DiscFEModel` (``system`` + banded solve).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

KELVIN = 273.15
_BLOCK = 32  # members per kernel block at least: work arrays of N = 150 x 4 stay in L2
# A block takes as many members as keep its work arrays (the L bands, T, D, M / dt and the
# right-hand side: L + 4 arrays of (n, members)) in a core's L2 cache (1 MiB here): fewer
# blocks pay the member loops' set-up and remainders fewer times (a 15 x 6 mesh's 83 sigma
# points in one block instead of 32 + 32 + 19: 86 instead of 100 µs a step)
_CACHE_BYTES = 1 << 20
_WORK_ROWS = 4  # T, D, M / dt and the right-hand side


def ramp_table(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A table linear between points and constant outside as ramps (branch-free).

    ``y(t) = y_0 + sum_m slope_m * clip(t - x_m, 0, width_m)``, identical to
    :func:`numpy.interp`; the kernel evaluates it with min/max only so it vectorises.

    Returns
    -------
    x0, slope, width : ndarray
    y0 : float
    """
    return x[:-1].copy(), np.diff(y) / np.diff(x), np.diff(x), float(y[0])


@numba.njit(cache=True, nogil=True, inline="always", fastmath=True)
def _ramps_nb(
    v: np.ndarray, t: np.ndarray, m: int, tab: tuple[np.ndarray, np.ndarray, np.ndarray, float]
) -> None:  # pragma: no cover - compiled
    """``v[i] = y(t[i])`` of a :func:`ramp_table` for the first ``m`` entries of flat
    arrays, segment by segment: one long loop per segment vectorises, where a loop over
    the few segments per value (or per short row of members) pays its set-up each time
    (with the larger blocks of :func:`step_nb`, a step of a 15 x 6 mesh's 83 sigma
    points 112-126 -> 90 µs, of a 150 x 4 mesh's 91 members 1200 -> 520-1060 µs)."""
    x0, slope, width, y0 = tab
    for i in range(m):
        v[i] = y0
    for j in range(x0.size):
        a, s, w = x0[j], slope[j], width[j]
        for i in range(m):
            v[i] += s * min(max(t[i] - a, 0.0), w)


@numba.njit(cache=True, nogil=True, inline="always", fastmath=True)
def _matrices_nb(  # pragma: no cover - compiled
    Tmt: np.ndarray, h: np.ndarray, kz: np.ndarray, N: int, L: int, dt: float,
    cap_geo: np.ndarray, cond_geo: np.ndarray, z_geo: np.ndarray, area: np.ndarray,
    c_tab: tuple[np.ndarray, np.ndarray, np.ndarray, float],
    k_tab: tuple[np.ndarray, np.ndarray, np.ndarray, float],
    z_tab: tuple[np.ndarray, np.ndarray, np.ndarray, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``M/dt + A_cond + A_conv`` of eq. 15 at ``Tmt`` (n, Bm): diagonal D, bands E
    (``E[o - 1, s] = A[s + o, s]``) and ``M/dt``."""
    n, Bm = Tmt.shape
    inv_dt = 1.0 / dt
    # matrices: D = diagonal, E[o - 1, s] = A[s + o, s]; Md = M / dt (eq. 15)
    D = np.empty((n, Bm))
    Md = np.empty((n, Bm))
    E = np.zeros((L, n, Bm))
    # the properties first, each table over all its nodes or interfaces and members at
    # once (flat, member fastest), into the arrays that take them (D holds the interface
    # temperatures meanwhile): c(T) into Md, k(T) at the radial interfaces (s, s + L)
    # into E[L - 1], the axial table at the pairs (s, s + 1) into E[0]
    Tf, Df, Mf = Tmt.ravel(), D.ravel(), Md.ravel()
    _ramps_nb(Mf, Tf, n * Bm, c_tab)
    m = (n - L) * Bm
    for i in range(m):
        Df[i] = 0.5 * (Tf[i] + Tf[i + L * Bm])
    _ramps_nb(E[L - 1].ravel(), Df, m, k_tab)
    if L > 1:
        m = (n - 1) * Bm
        for i in range(m):
            Df[i] = 0.5 * (Tf[i] + Tf[i + Bm])
        _ramps_nb(E[0].ravel(), Df, m, z_tab)
    for s in range(n):
        for b in range(Bm):
            Md[s, b] *= cap_geo[s] * inv_dt
            D[s, b] = Md[s, b] + h[b] * area[s]
    for s in range(n - L):
        g = cond_geo[s]
        for b in range(Bm):
            G = g * E[L - 1, s, b]
            D[s, b] += G
            D[s + L, b] += G
            E[L - 1, s, b] = -G
    for i in range(N):
        for j in range(L - 1):
            s = i * L + j
            zg = z_geo[i * (L - 1) + j]
            for b in range(Bm):
                G = kz[b] * zg * E[0, s, b]
                D[s, b] += G
                D[s + 1, b] += G
                E[0, s, b] = -G
        if L > 1 and i < N - 1:  # nodes (i, L - 1) and (i + 1, 0) are not coupled
            for b in range(Bm):
                E[0, i * L + L - 1, b] = 0.0
    return D, E, Md


@numba.njit(cache=True, nogil=True, inline="always", fastmath=True)
def _rhs_nb(  # pragma: no cover - compiled
    Tt: np.ndarray, Md: np.ndarray, h: np.ndarray, ta: np.ndarray, Qs: np.ndarray,
    load: np.ndarray, N: int, L: int, area: np.ndarray, rad_geo: np.ndarray,
) -> np.ndarray:
    """``M/dt T + p`` (n, B) of eq. 15: convection to ambient, friction, lagged
    radiation; ``Md`` and ``h`` one column or value per matrix (B or 1 shared)."""
    n, B = Tt.shape
    Bm = Md.shape[1]
    MdB, hB = Md, h
    if Bm != B:
        MdB = np.empty((n, B))
        for s in range(n):
            for b in range(B):
                MdB[s, b] = Md[s, 0]
        hB = np.full(B, h[0])
    X = np.empty((n, B))
    for s in range(n):
        for b in range(B):
            X[s, b] = MdB[s, b] * Tt[s, b] + hB[b] * area[s] * ta[b]
    shared_load = load.shape[0] != B
    for i in range(N):
        s = i * L
        for b in range(B):
            tk = Tt[s, b] + KELVIN
            tak = ta[b] + KELVIN
            share = load[0, i] if shared_load else load[b, i]
            X[s, b] += Qs[b] * share - rad_geo[i] * (
                (tk * tk) * (tk * tk) - (tak * tak) * (tak * tak)
            )
    return X


@numba.njit(cache=True, nogil=True, inline="always", fastmath=True)
def _ldl_solve_nb(  # pragma: no cover - compiled
    D: np.ndarray, E: np.ndarray, X: np.ndarray, L: int
) -> None:
    """Factor the banded matrices (D, E) as LDL^T and solve them for ``X`` (n, B) in
    place; a single shared matrix (one column) is spread over the B members."""
    n, B = X.shape
    Bm = D.shape[1]
    # LDL^T (as banded._factor_numpy), D <- 1/D
    for s in range(n):
        m = min(L, n - 1 - s)
        for b in range(Bm):
            D[s, b] = 1.0 / D[s, b]
        for o1 in range(1, m + 1):
            for o2 in range(o1, m + 1):
                if o2 == o1:
                    for b in range(Bm):
                        D[s + o1, b] -= E[o1 - 1, s, b] * E[o1 - 1, s, b] * D[s, b]
                else:
                    for b in range(Bm):
                        E[o2 - o1 - 1, s + o1, b] -= E[o2 - 1, s, b] * E[o1 - 1, s, b] * D[s, b]
        for o in range(m):
            for b in range(Bm):
                E[o, s, b] *= D[s, b]
    if Bm != B:  # one shared factor: spread it so the solve loops stay gather-free
        D1, E1 = D, E
        D = np.empty((n, B))
        E = np.empty((L, n, B))
        for s in range(n):
            for b in range(B):
                D[s, b] = D1[s, 0]
                for o in range(L):
                    E[o, s, b] = E1[o, s, 0]
    for s in range(n):
        for o in range(1, min(L, n - 1 - s) + 1):
            for b in range(B):
                X[s + o, b] -= E[o - 1, s, b] * X[s, b]
    for s in range(n):
        for b in range(B):
            X[s, b] *= D[s, b]
    for s in range(n - 2, -1, -1):
        for o in range(1, min(L, n - 1 - s) + 1):
            for b in range(B):
                X[s, b] -= E[o - 1, s, b] * X[s + o, b]


@numba.njit(cache=True, nogil=True, fastmath=True)
def _step_block(  # pragma: no cover - compiled; equal to system() + banded solve (tested)
    out: np.ndarray,
    T: np.ndarray,
    Tm: np.ndarray,
    Qs: np.ndarray,
    ta: np.ndarray,
    h: np.ndarray,
    kz: np.ndarray,
    load: np.ndarray,
    N: int,
    L: int,
    dt: float,
    cap_geo: np.ndarray,
    cond_geo: np.ndarray,
    z_geo: np.ndarray,
    area: np.ndarray,
    rad_geo: np.ndarray,
    c_tab: tuple[np.ndarray, np.ndarray, np.ndarray, float],
    k_tab: tuple[np.ndarray, np.ndarray, np.ndarray, float],
    z_tab: tuple[np.ndarray, np.ndarray, np.ndarray, float],
) -> np.ndarray:
    """Eq. 15 for B members into ``out``; matrices from ``Tm`` (B rows or 1 shared).

    ``load`` holds the nodal shares of ``Q``, one row per member or one shared row.
    Geometric factors are per layer, flattened node-major: ``cap_geo`` (N L),
    ``cond_geo`` ((N - 1) L, one per radial element and layer), ``z_geo`` (N (L - 1),
    one per interface).

    ``h`` and ``kz`` have one value per matrix; ``Qs`` (= scale Q) and ``ta`` per member.
    Batch innermost: the LDL^T recurrences of different members are independent, so
    the inner loops vectorise instead of waiting on one member's divisions.
    """
    B, n = T.shape
    Bm = Tm.shape[0]
    Tt = np.empty((n, B))
    for b in range(B):
        for s in range(n):
            Tt[s, b] = T[b, s]
    # the matrices' temperatures always from Tm: a block of one member of a shared Tm
    # (Bm == B == 1) must not take its own T instead
    Tmt = np.empty((n, Bm))
    for b in range(Bm):
        for s in range(n):
            Tmt[s, b] = Tm[b, s]
    D, E, Md = _matrices_nb(Tmt, h, kz, N, L, dt, cap_geo, cond_geo, z_geo, area, c_tab,
                            k_tab, z_tab)
    X = _rhs_nb(Tt, Md, h, ta, Qs, load, N, L, area, rad_geo)
    _ldl_solve_nb(D, E, X, L)
    for b in range(B):
        for s in range(n):
            out[b, s] = X[s, b]


@numba.njit(cache=True, nogil=True)
def step_nb(  # pragma: no cover - compiled
    T: np.ndarray,
    Tm: np.ndarray,
    Qs: np.ndarray,
    ta: np.ndarray,
    h: np.ndarray,
    kz: np.ndarray,
    load: np.ndarray,
    *geometry: Any,
) -> np.ndarray:
    """:func:`_step_block` over equal blocks of members whose work arrays stay in cache
    (at least :data:`_BLOCK` members a block)."""
    B, n = T.shape
    out = np.empty_like(T)
    if B == 0:
        return out
    shared = Tm.shape[0] != B
    shared_load = load.shape[0] != B
    fits = _CACHE_BYTES // (8 * n * (geometry[1] + _WORK_ROWS))
    blocks = -(-B // max(_BLOCK, fits))
    size = -(-B // blocks)
    for b0 in range(0, B, size):
        b1 = min(b0 + size, B)
        m0, m1 = (0, 1) if shared else (b0, b1)
        l0, l1 = (0, 1) if shared_load else (b0, b1)
        _step_block(
            out[b0:b1], T[b0:b1], Tm[m0:m1], Qs[b0:b1], ta[b0:b1], h[m0:m1], kz[m0:m1],
            load[l0:l1], *geometry,
        )  # fmt: skip
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _readout_nb(out: np.ndarray, T: np.ndarray, HT: np.ndarray) -> None:  # pragma: no cover
    """``out = T HT`` by loops: an array assignment would compile numba's shape-error
    machinery, seconds of every first run."""
    B, n = T.shape
    for b in range(B):
        for j in range(HT.shape[1]):
            t = 0.0
            for i in range(n):
                t += T[b, i] * HT[i, j]
            out[b, j] = t


@numba.njit(cache=True, nogil=True)
def run_nb(  # pragma: no cover - compiled
    T0: np.ndarray,
    Qs: np.ndarray,
    ta: np.ndarray,
    h: np.ndarray,
    kz: np.ndarray,
    loads: np.ndarray,
    zone: np.ndarray,
    HT: np.ndarray,
    fb: np.ndarray,
    fb_at: np.ndarray,
    *geometry: Any,
) -> np.ndarray:
    """:func:`step_nb` through all K steps, the readout ``T HT`` kept per step.

    ``fb`` (B, 3) = (gain, centre, span) scales each member's power by
    ``1 + gain clip((T_c - centre)/span, -1, 1)``, ``T_c`` the mean of the state at
    ``fb_at`` (:meth:`DiscFEModel.run_readout`).
    """
    K, B = Qs.shape
    out = np.empty((K + 1, B, HT.shape[1]))
    T = T0.copy()
    Qk = np.empty(B)
    _readout_nb(out[0], T, HT)
    for k in range(K):
        for b in range(B):
            t_c = 0.0
            for i in fb_at:
                t_c += T[b, i]
            x = (t_c / fb_at.size - fb[b, 1]) / fb[b, 2]
            Qk[b] = Qs[k, b] * (1.0 + fb[b, 0] * min(max(x, -1.0), 1.0))
        T = step_nb(T, T, Qk, ta[k], h[k], kz, loads[zone[k]], *geometry)
        _readout_nb(out[k + 1], T, HT)
    return out
