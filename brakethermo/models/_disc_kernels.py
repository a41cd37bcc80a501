"""The disc filter's transition and process noise compiled into the UKF's step loop.

:meth:`DiscStateSpace.f` steps every sigma point through one compiled FE call, but each
step still crosses the interpreter: reading the parameters out of the sigma set, the
process noise, argument checks (a third of a 41-state step, 30-40 µs of ~120), and two
filters on two threads queue for the interpreter's lock between their compiled calls.
:func:`ukf_disc_steps` runs a whole span of steps — :func:`disc_transition` (the same
arithmetic as ``f``), the noise of :meth:`DiscStateSpace.noise` and the UKF kernel's
step — in one call that releases the lock. The tests hold it equal to the Python loop.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from brakethermo.estimation._kernels import _sigma, ukf_step
from brakethermo.thermal._fe_kernels import step_nb

# columns of the transition's parameter table (-1: the state has no such parameter)
COL_H, COL_FACTOR, COL_SCALE, COL_KZ, COL_BALANCE, COL_SENSOR = range(6)


@njit(cache=True, nogil=True)
def disc_transition(X, j, Xf, inputs, cols, lower, floats, contact, loads, sensor_row,
                    geometry):  # pragma: no cover - compiled; equal to f (tested)
    """``Xf = f(X, j)`` of :class:`DiscStateSpace` (eq. 15, 50) by loops.

    ``inputs`` = (q_brk, t_amb, h), (K, 1) or (K, B): per step, shared or one column
    per member (h (0, 1) when it is a state); ``cols`` the
    state columns of :data:`COL_H` ...; ``lower`` each column's floor (``max(theta,
    lower)``); ``floats`` = (k_z ratio of the model, μ β, μ T_mid, μ span, balance cap,
    sensor gain); ``loads`` = (the model's load (1, N), load at b = 0, dload/db).
    """
    q_brk, t_amb, h_k = inputs
    B, n = X.shape
    n_temp = geometry[0] * geometry[1]
    kz0, beta, t_mid, span, b_max, alpha = floats
    h = np.empty(B)
    kz = np.empty(B)
    Qs = np.empty(B)
    ta = np.empty(B)
    T = np.empty((B, n_temp))
    for b in range(B):
        ta[b] = t_amb[j, b if t_amb.shape[1] > 1 else 0]
        c = cols[COL_H]
        h[b] = h_k[j, b if h_k.shape[1] > 1 else 0] if c < 0 else max(X[b, c], lower[c])
        c = cols[COL_FACTOR]
        if c >= 0:
            h[b] *= max(X[b, c], lower[c])
        c = cols[COL_SCALE]
        scale = 1.0 if c < 0 else max(X[b, c], lower[c])
        if beta != 0.0:
            t_c = 0.0
            for i in contact:
                t_c += X[b, i]
            u = (t_c / contact.size - t_mid) / span
            scale *= 1.0 + beta * min(max(u, -1.0), 1.0)
        Qs[b] = q_brk[j, b if q_brk.shape[1] > 1 else 0] * scale
        c = cols[COL_KZ]
        kz[b] = kz0 if c < 0 else max(X[b, c], lower[c]) * kz0
        for i in range(n_temp):
            T[b, i] = X[b, i]
    c = cols[COL_BALANCE]
    load = loads[0]
    if c >= 0:
        load0, dload = loads[1][0], loads[2][0]
        load = np.empty((B, load0.size))
        for b in range(B):
            tilt = min(max(X[b, c], lower[c]), b_max)
            for i in range(load0.size):
                load[b, i] = load0[i] + tilt * dload[i]
    out = step_nb(T, T, Qs, ta, h, kz, load, *geometry)
    for b in range(B):
        for i in range(n_temp):
            Xf[b, i] = out[b, i]
        for i in range(n_temp, n):
            Xf[b, i] = X[b, i]
    s = cols[COL_SENSOR]
    if s >= 0:
        for b in range(B):
            face = 0.0
            for i in range(n_temp):
                face += out[b, i] * sensor_row[i]
            Xf[b, s] = X[b, s] + alpha * (face - X[b, s])


@njit(cache=True, nogil=True)
def disc_noise(j, Q, noise, q_brk):  # pragma: no cover - compiled; equal to Q (tested)
    """``Q`` of step ``j`` in place: white base, the crown split times the squared
    braking power, the parameters' random walks (:meth:`DiscStateSpace.noise`)."""
    base, crown, param_idx, step_var, moving = noise
    n = Q.shape[0]
    q2 = q_brk[j, 0] * q_brk[j, 0]
    for a in range(n):
        for b in range(n):
            Q[a, b] = base[a, b] + q2 * crown[a, b]
    for p in range(param_idx.size):
        i = param_idx[p]
        Q[i, i] = step_var[p] * moving[j, p]


@njit(cache=True, nogil=True)
def ukf_disc_steps(k0, k1, offset, work, W, par, thr, H, R, y, M, st, cov, gs, iv, sc,
                   ic, rej, ro, inputs, cols, lower, floats, contact, loads, sensor_row,
                   noise, geometry):  # pragma: no cover - compiled; equal to the loop
    """Filter steps ``k0 .. k1 - 1`` (eq. 32-37 and the update): the transition of
    model step ``k + offset``, its noise and :func:`ukf_step` with the UKF kernel's
    arguments (``work`` ... ``ro``, see :mod:`brakethermo.estimation._kernels`)."""
    n = work.shape[1]
    B = 2 * n + 1
    X = work[:B]
    Xf = np.empty((B, n))
    Q = np.empty((n, n))
    for k in range(k0, k1):
        j = k + offset
        disc_transition(X, j, Xf, inputs, cols, lower, floats, contact, loads,
                        sensor_row, geometry)
        disc_noise(j, Q, noise, inputs[0])
        ukf_step(k, Xf, work, W, par, thr, Q, H, R, y, M, st, cov, gs, iv, sc, ic, rej,
                 ro)


@njit(cache=True, nogil=True)
def ukf_reduced_steps(k0, k1, offset, work, W, par, thr, H, R, y, M, st, cov, gs, iv, sc,
                      ic, rej, ro, L, inputs, cols, lower, floats, contact, loads,
                      sensor_row, noise, geometry):  # pragma: no cover - compiled
    """:func:`ukf_disc_steps` on reduced coordinates, ``x_full = L x``
    (:class:`~brakethermo.models.reduced.ReducedStateSpace`): each sigma point lifted
    to the full model, stepped, and projected back, ``x' = L' f(L x)``; ``noise`` is
    the reduced one. ``L`` (n_full, n) has orthonormal columns.

    The sigma set in ``work`` is the one the UKF kernel drew from the posterior mean
    ``x`` and factor ``S`` that ``work`` holds with it (``x``, ``x +- c S_j``): lifted, it
    is ``L x +- c (L S)_j``, one product with the n columns of ``S`` instead of the
    2n + 1 sigma points (equal but for rounding)."""
    n = work.shape[1]
    B = 2 * n + 1
    n_full = L.shape[0]
    c = par[0]
    S = work[B + n : B + 2 * n]
    x = work[B + 2 * n]
    x_full = np.empty(n_full)
    LS = np.empty((n_full, n))
    X_full = np.empty((B, n_full))
    Xf_full = np.empty((B, n_full))
    Xf = np.empty((B, n))
    Q = np.empty((n, n))
    for k in range(k0, k1):
        j = k + offset
        np.dot(L, x, x_full)
        np.dot(L, S, LS)
        _sigma(x_full, LS, c, X_full)
        disc_transition(X_full, j, Xf_full, inputs, cols, lower, floats, contact, loads,
                        sensor_row, geometry)
        np.dot(Xf_full, L, Xf)
        disc_noise(j, Q, noise, inputs[0])
        ukf_step(k, Xf, work, W, par, thr, Q, H, R, y, M, st, cov, gs, iv, sc, ic, rej,
                 ro)


@njit(cache=True, nogil=True)
def disc_replay(Xs, w, k0, inputs, cols, lower, floats, contact, loads, sensor_row,
                geometry):  # pragma: no cover - compiled; equal to the loop (tested)
    """``Xs[k + 1] = f(Xs[k], k0 + k) + w[k]`` for every k, in place: the model
    stepped through the session with a correction added after each step (``whatif``)."""
    K, B, n = Xs.shape
    Xf = np.empty((B, n))
    for k in range(K - 1):
        disc_transition(Xs[k], k0 + k, Xf, inputs, cols, lower, floats, contact, loads,
                        sensor_row, geometry)
        for b in range(B):
            for i in range(n):
                Xs[k + 1, b, i] = Xf[b, i] + w[k, b, i]


def run_steps(spec: tuple[Any, ...], k0: int, k1: int, offset: int, work: np.ndarray,
              *kernel_args: Any, lift: np.ndarray | None = None) -> None:
    """:func:`ukf_disc_steps` with the state space's ``spec`` (its arrays, fixed per run),
    or :func:`ukf_reduced_steps` on the reduced coordinates of ``lift``."""
    if lift is None:
        ukf_disc_steps(k0, k1, offset, work, *kernel_args, *spec)
    else:
        ukf_reduced_steps(k0, k1, offset, work, *kernel_args, lift, *spec)
