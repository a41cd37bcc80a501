"""Numba kernels running everything of a UKF or EKF step except the model call.

For small states (n up to a few tens) the per-step cost of a numpy UKF is Python and
dispatch overhead, not arithmetic. These kernels do one whole step — unscented moments
of the propagated sigma set (eq. 36-37), the smoother's gain, the linear measurement
update (eq. 28-31), covariance repair and the next sigma set (eq. 32-34) — in one
compiled call, so a step costs one model call plus one kernel call. They mirror
``_forward.run_forward`` operation by operation; the tests hold the two paths equal.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_LOG_2PI = math.log(2.0 * math.pi)
# Below this state size plain loops beat BLAS calls, whose fixed cost dominates tiny
# products; above it the O(n^3) products go to BLAS.
SMALL_N = 12


@njit(cache=True, nogil=True)
def _symmetrise(P):
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = v
            P[j, i] = v


@njit(cache=True, nogil=True)
def _put(dst, src, transpose):
    """dst[:, :] = src (or src') by loops: an array assignment compiles numba's shape-error
    machinery, seconds of a first run for a copy."""
    n, m = dst.shape
    for i in range(n):
        for j in range(m):
            dst[i, j] = src[j, i] if transpose else src[i, j]


@njit(cache=True, nogil=True)
def _chol(P, L):
    """Lower Cholesky factor into L; False if P is not (numerically) positive definite."""
    n = P.shape[0]
    for j in range(n):
        s = P[j, j]
        for p in range(j):
            s -= L[j, p] * L[j, p]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            t = P[i, j]
            for p in range(j):
                t -= L[i, p] * L[j, p]
            L[i, j] = t / d
        for i in range(j):
            L[i, j] = 0.0
    return True


@njit(cache=True, nogil=True)
def chol_downdate(L, v):
    """Lower factor of L L' - v v' in place, O(n^2); False (L spoilt) if not SPD.

    The exact linear update with one measurement (eq. 47) is the rank-1 downdate
    P - K S K' = P - v v', v = C_xy / sqrt(S): the posterior's factor follows from the
    prior's (already computed for the smoother's gain) without an O(n^3) Cholesky.
    """
    n = v.shape[0]
    w = v.copy()
    for k in range(n):
        lkk = L[k, k]
        r2 = lkk * lkk - w[k] * w[k]
        if not r2 > 0.0:
            return False
        r = math.sqrt(r2)
        c = r / lkk
        s = w[k] / lkk
        L[k, k] = r
        for i in range(k + 1, n):
            lik = (L[i, k] - s * w[i]) / c
            L[i, k] = lik
            w[i] = c * w[i] - s * lik
    return True


@njit(cache=True, nogil=True)
def _repair(P, abs_floor):
    """Eigenvalue clipping in place, as CovarianceGuard.repair."""
    n = P.shape[0]
    for i in range(n):
        for j in range(n):
            if not math.isfinite(P[i, j]):
                P[i, j] = 0.0
    _symmetrise(P)
    w, V = np.linalg.eigh(P)
    wmax = 0.0
    for i in range(n):
        wmax = max(wmax, abs(w[i]))
    floor = max(1e-12 * wmax, abs_floor)
    for i in range(n):
        w[i] = max(w[i], floor)
    # V diag(w) V' by loops: array expressions here would compile numba's shape-error
    # machinery (seconds on a first run) for a path taken once in a thousand steps
    for i in range(n):
        for j in range(i + 1):
            t = 0.0
            for a in range(n):
                t += V[i, a] * w[a] * V[j, a]
            P[i, j] = t
            P[j, i] = t


@njit(cache=True, nogil=True)
def _factor(P, L, k, abs_floor, repairs):
    """Factor P, repairing (and counting in repairs[k]) if needed; P may be changed."""
    if _chol(P, L):
        return
    repairs[k] += 1
    _repair(P, abs_floor)
    if _chol(P, L):
        return
    n = P.shape[0]
    jitter = abs_floor + 1e-9 * np.max(np.diag(P))
    for i in range(n):
        P[i, i] += jitter
    _chol(P, L)


@njit(cache=True, nogil=True)
def _gain_multi(S, Cxy, nu, Kg, k, repairs, abs_floor):  # pragma: no cover - compiled
    """Gain ``Kg = Cxy S^-1`` (eq. 45, into ``Kg``), NIS and log det S of a vector
    innovation, by the Cholesky factor of S (repaired and counted when S is not positive
    definite)."""
    n, mk = Cxy.shape
    _symmetrise(S)
    Ls = np.empty((mk, mk))
    if not _chol(S, Ls):
        repairs[k] += 1
        _repair(S, abs_floor)
        _chol(S, Ls)
    logdet = 0.0
    for a in range(mk):
        logdet += 2.0 * math.log(Ls[a, a])
    # K' = S^-1 Cxy' by two triangular solves, column by column of Cxy'
    for i in range(n):
        z = np.empty(mk)
        for a in range(mk):
            t = Cxy[i, a]
            for b in range(a):
                t -= Ls[a, b] * z[b]
            z[a] = t / Ls[a, a]
        for a in range(mk - 1, -1, -1):
            t = z[a]
            for b in range(a + 1, mk):
                t -= Ls[b, a] * Kg[i, b]
            Kg[i, a] = t / Ls[a, a]
    z = np.empty(mk)
    for a in range(mk):
        t = nu[a]
        for b in range(a):
            t -= Ls[a, b] * z[b]
        z[a] = t / Ls[a, a]
    nis_k = 0.0
    for a in range(mk):
        nis_k += z[a] * z[a]
    return nis_k, logdet


@njit(cache=True, nogil=True)
def _update(
    k, x, P, H, R, y, gate_thr, abs_floor, repairs, innov, innov_var, nis, loglik, n_obs, rejected
):
    """Linear measurement update with missing components (eq. 28-31), in place."""
    n = x.shape[0]
    m = y.shape[0]
    idx = np.empty(m, dtype=np.int64)
    mk = 0
    for i in range(m):
        if math.isfinite(y[i]):
            idx[mk] = i
            mk += 1
    if mk == 0:
        return
    Cxy = np.empty((n, mk))
    for i in range(n):
        for a in range(mk):
            r = idx[a]
            t = 0.0
            for j in range(n):
                t += P[i, j] * H[r, j]
            Cxy[i, a] = t
    S = np.empty((mk, mk))
    nu = np.empty(mk)
    for a in range(mk):
        r = idx[a]
        t = y[r]
        for j in range(n):
            t -= H[r, j] * x[j]
        nu[a] = t
        for b in range(mk):
            s = R[r, idx[b]]
            for j in range(n):
                s += H[r, j] * Cxy[j, b]
            S[a, b] = s
    Kg = np.empty((n, mk))
    if mk == 1:
        s = S[0, 0]
        if not s > 0.0:
            repairs[k] += 1
            s = max(s, max(1e-12 * abs(s), abs_floor))
            S[0, 0] = s
        for i in range(n):
            Kg[i, 0] = Cxy[i, 0] / s
        nis_k = nu[0] * nu[0] / s
        logdet = math.log(s)
    else:
        nis_k, logdet = _gain_multi(S, Cxy, nu, Kg, k, repairs, abs_floor)
    for a in range(mk):
        innov[k, idx[a]] = nu[a]
        innov_var[k, idx[a]] = S[a, a]
    if gate_thr[mk] > 0.0 and nis_k > gate_thr[mk]:
        rejected[k] = True
        return
    for i in range(n):
        t = 0.0
        for a in range(mk):
            t += Kg[i, a] * nu[a]
        x[i] += t
    for i in range(n):
        for j in range(i, n):
            t = 0.0
            for a in range(mk):
                t += Kg[i, a] * Cxy[j, a]
            # eq. 47 with K S K' = K C_xy'; symmetrised as in the numpy path
            v = P[i, j] - 0.5 * (t + _dot_row(Kg, Cxy, j, i, mk))
            P[i, j] = v
            P[j, i] = v
    n_obs[k] = mk
    nis[k] = nis_k
    loglik[k] = -0.5 * (nis_k + logdet + mk * _LOG_2PI)


@njit(cache=True, nogil=True)
def _dot_row(A, B, i, j, mk):
    t = 0.0
    for a in range(mk):
        t += A[i, a] * B[j, a]
    return t


@njit(cache=True, nogil=True)
def _sigma(x, L, c, X):
    """Sigma points ``x`` and ``x +- c L[:, j]`` into the rows of X (eq. 32-34); L is
    (n, m): square in the filter, a lifted factor (full states by modes) in the reduced
    disc filter."""
    n, m = L.shape
    for i in range(n):
        X[0, i] = x[i]
    for j in range(m):
        for i in range(n):
            d = c * L[i, j]
            X[1 + j, i] = x[i] + d
            X[1 + m + j, i] = x[i] - d


@njit(cache=True, nogil=True)
def _record_posterior(k, x, P, x_filt, var_filt, P_filt_all, full, M, ro, ro_var):
    n = x.shape[0]
    for i in range(n):
        x_filt[k, i] = x[i]
        var_filt[k, i] = P[i, i]
    if full:
        _put(P_filt_all[k], P, False)
    for r in range(M.shape[0]):
        t = 0.0
        v = 0.0
        for i in range(n):
            t += M[r, i] * x[i]
            mp = 0.0
            for j in range(n):
                mp += M[r, j] * P[j, i]
            v += mp * M[r, i]
        ro[k, r] = t
        ro_var[k, r] = v


@njit(cache=True, nogil=True)
def _views(work):
    """Sigma set X, posterior P, its factor L and mean x, packed in one work array."""
    n = work.shape[1]
    B = 2 * n + 1
    return work[:B], work[B : B + n], work[B + n : B + 2 * n], work[B + 2 * n]


@njit(cache=True, nogil=True)
def ukf_first(work, par, gate_thr, H, R, y, M, st, cov, iv, sc, ic, rej, ro):
    """Step 0: record the prior, update with y[0], factor and draw the first sigma set.

    ``work`` holds [X; P; L; x] (see ``_views``), ``par`` = [c, eigenvalue floor]; the
    output stacks are those of ``_forward.Buffers``.
    """
    X, P, L, x = _views(work)
    c, abs_floor = par[0], par[1]
    k0 = np.int64(0)  # not the literal 0: that compiles the update chain a second time
    if _update_step(k0, x, P, L, abs_floor, gate_thr, H, R, y, M, st, cov, iv, sc, ic, rej, ro):
        _sigma(x, L, c, X)


@njit(cache=True, nogil=True)
def ukf_step(k, Xf, work, W, par, gate_thr, Q, H, R, y, M, st, cov, gs, iv, sc, ic, rej, ro):
    """From the propagated sigma set Xf = f(X, k): prior of step k+1, gains, update, next set.

    Arguments as :func:`ukf_first`, plus ``W`` = [Wm; Wc] and the gain stack ``gs``.
    """
    X, P, L, x = _views(work)
    Wm, Wc = W[0], W[1]
    c, abs_floor = par[0], par[1]
    n = x.shape[0]
    B = Xf.shape[0]
    xp = np.zeros(n)
    for b in range(B):
        for i in range(n):
            xp[i] += Wm[b] * Xf[b, i]  # eq. 36
    D = Xf - xp
    # C_k = L (D+ - D-) / (2c): the sigma deviations are +-c L_j, weights 1/(2c^2)
    Dd = (D[1 : n + 1] - D[n + 1 :]) * (0.5 / c)
    if n <= SMALL_N:
        Pp = Q.copy()
        for b in range(B):
            for i in range(n):
                a = Wc[b] * D[b, i]
                for j in range(n):
                    Pp[i, j] += a * D[b, j]  # eq. 37
        C = np.zeros((n, n))
        for i in range(n):
            for j in range(i + 1):
                a = L[i, j]
                for col in range(n):
                    C[i, col] += a * Dd[j, col]
    else:
        Pp = (D.T * Wc) @ D + Q  # eq. 37
        C = L @ Dd
    if _advance(k, xp, Pp, C, P, L, x, abs_floor, gate_thr, H, R, y, M, st, cov, gs, iv, sc,
                ic, rej, ro):
        _sigma(x, L, c, X)


@njit(cache=True, nogil=True)
def _advance(k, xp, Pp, C, P, L, x, abs_floor, gate_thr, H, R, y, M, st, cov, gs, iv, sc, ic,
             rej, ro):
    """Shared by both filters from the prior of step k+1 (xp, Pp) and C_k = cov(x_k, x_k+1).

    The smoother's gain and Sigma, the measurement update of step k+1, the factor of its
    posterior and the records; True if another step follows.
    """
    n = x.shape[0]
    kp = k + 1
    full = cov.shape[1] > 0
    gains = gs.shape[1] > 0
    _symmetrise(Pp)
    if full:
        _put(cov[2, k], C, False)
    if gains:
        Lp = np.empty((n, n))
        _factor(Pp, Lp, kp, abs_floor, ic[1])
        # G' = (Lp Lp')^-1 C' by forward then backward substitution, rows contiguous
        Gt = np.ascontiguousarray(C.T)
        for a in range(n):
            for b in range(a):
                lab = Lp[a, b]
                for col in range(n):
                    Gt[a, col] -= lab * Gt[b, col]
            inv = 1.0 / Lp[a, a]
            for col in range(n):
                Gt[a, col] *= inv
        for a in range(n - 1, -1, -1):
            for b in range(a + 1, n):
                lba = Lp[b, a]
                for col in range(n):
                    Gt[a, col] -= lba * Gt[b, col]
            inv = 1.0 / Lp[a, a]
            for col in range(n):
                Gt[a, col] *= inv
        if n <= SMALL_N:
            CG = np.zeros((n, n))
            for i in range(n):
                for a in range(n):
                    cia = C[i, a]
                    for j in range(n):
                        CG[i, j] += cia * Gt[a, j]
        else:
            CG = C @ Gt  # (G C')'
        for i in range(n):
            for j in range(i, n):
                v = P[i, j] - 0.5 * (CG[i, j] + CG[j, i])
                gs[1, k, i, j] = v
                gs[1, k, j, i] = v
        _put(gs[0, k], Gt, True)
    for i in range(n):
        x[i] = xp[i]
    _put(P, Pp, False)
    return _update_step(kp, x, P, L, abs_floor, gate_thr, H, R, y, M, st, cov, iv, sc, ic, rej, ro)


@njit(cache=True, nogil=True)
def _update_step(k, x, P, L, abs_floor, gate_thr, H, R, y, M, st, cov, iv, sc, ic, rej, ro):
    """Both filters at step k from its prior (x, P): record it, update with y[k] in place,
    factor the posterior into L when another step follows, record it; True if one does.
    """
    n = x.shape[0]
    for i in range(n):
        st[0, k, i] = x[i]
        st[1, k, i] = P[i, i]
    if cov.shape[1] > 0:
        _put(cov[0, k], P, False)
    _update(
        k, x, P, H, R, y[k], gate_thr, abs_floor, ic[1], iv[0], iv[1], sc[0], sc[1], ic[0], rej
    )  # fmt: skip
    more = k < st.shape[1] - 1
    if more:
        _factor(P, L, k, abs_floor, ic[1])  # the posterior as factored is the one stored
    _record_posterior(k, x, P, st[2], st[3], cov[1], cov.shape[1] > 0, M, ro[0], ro[1])
    return more


@njit(cache=True, nogil=True)
def _ekf_views(work):
    """Linearisation points X (n + 1), posterior P, its factor L, mean x, steps eps."""
    n = work.shape[1]
    return (work[: n + 1], work[n + 1 : 2 * n + 1], work[2 * n + 1 : 3 * n + 1],
            work[3 * n + 1], work[3 * n + 2])


@njit(cache=True, nogil=True)
def _fd_points(x, X, eps, rel_step):
    """x and x + eps_j e_j, eps_j = rel_step max(|x_j|, 1) (as ekf.batched_jacobian)."""
    n = x.shape[0]
    for j in range(n):
        eps[j] = rel_step * max(abs(x[j]), 1.0)
    for b in range(n + 1):
        for i in range(n):
            X[b, i] = x[i]
    for j in range(n):
        X[1 + j, j] += eps[j]


@njit(cache=True, nogil=True)
def ekf_first(work, par, gate_thr, H, R, y, M, st, cov, iv, sc, ic, rej, ro):
    """Step 0 of the EKF: record the prior, update with y[0], factor, linearisation points.

    ``work`` holds [X; P; L; x; eps] (see ``_ekf_views``), ``par`` = [forward-difference
    relative step, eigenvalue floor].
    """
    X, P, L, x, eps = _ekf_views(work)
    rel_step, abs_floor = par[0], par[1]
    k0 = np.int64(0)  # not the literal 0: that compiles the update chain a second time
    if _update_step(k0, x, P, L, abs_floor, gate_thr, H, R, y, M, st, cov, iv, sc, ic, rej, ro):
        _fd_points(x, X, eps, rel_step)


@njit(cache=True, nogil=True)
def ekf_step(k, GX, Fj, work, par, gate_thr, Q, H, R, y, M, st, cov, gs, iv, sc, ic, rej, ro):
    """From GX = f(X, k): prior of step k+1 (eq. 26-27 linearised), gains, update, next X.

    ``Fj`` is the analytic Jacobian at x (then GX holds f(x) only), or an empty (0, n)
    array: then the Jacobian is the forward difference of GX over the points X.
    """
    X, P, L, x, eps = _ekf_views(work)
    rel_step, abs_floor = par[0], par[1]
    n = x.shape[0]
    xp = GX[0].copy()
    if Fj.shape[0] == 0:
        F = np.empty((n, n))
        for j in range(n):
            for i in range(n):
                F[i, j] = (GX[1 + j, i] - xp[i]) / eps[j]
    else:
        F = Fj
    if n <= SMALL_N:
        C = np.zeros((n, n))  # C_k = P F'
        for i in range(n):
            for j in range(n):
                t = 0.0
                for a in range(n):
                    t += P[i, a] * F[j, a]
                C[i, j] = t
        Pp = Q.copy()  # F C + Q
        for i in range(n):
            for j in range(n):
                t = 0.0
                for a in range(n):
                    t += F[i, a] * C[a, j]
                Pp[i, j] += t
    else:
        C = P @ F.T
        Pp = F @ C + Q
    if _advance(k, xp, Pp, C, P, L, x, abs_floor, gate_thr, H, R, y, M, st, cov, gs, iv, sc,
                ic, rej, ro):
        _fd_points(x, X, eps, rel_step)


@njit(cache=True, nogil=True)
def rts_backward(
    x_filt, x_pred, G_all, Sigma_all, x_last, P_last, x_s, var_s, P_all, full, M, ro, ro_var,
    P_first,
):
    """Backward RTS recursion with stored gains (see urts.py), in place into the outputs.

    The recursion starts from the smoothed (x_last, P_last) of the last step and leaves
    the smoothed covariance of step 0 in ``P_first`` (a window's hand-over).
    """
    K, n = x_filt.shape
    xs = x_last.copy()
    Ps = P_last.copy()
    d = np.empty(n)
    for k in range(K - 1, -1, -1):
        if k < K - 1:
            for i in range(n):
                d[i] = xs[i] - x_pred[k + 1, i]
            for i in range(n):
                t = x_filt[k, i]
                for j in range(n):
                    t += G_all[k, i, j] * d[j]
                xs[i] = t
            G = G_all[k].astype(np.float64)
            GPG = (G @ Ps) @ G.T
            for i in range(n):
                for j in range(i, n):
                    v = 0.5 * (Sigma_all[k, i, j] + Sigma_all[k, j, i] + GPG[i, j] + GPG[j, i])
                    Ps[i, j] = v
                    Ps[j, i] = v
        for i in range(n):
            x_s[k, i] = xs[i]
            var_s[k, i] = Ps[i, i]
        if full:
            _put(P_all[k], Ps, False)
        _record_posterior(k, xs, Ps, x_s, var_s, P_all, False, M, ro, ro_var)
    _put(P_first, Ps, False)
