"""Unscented Kalman filter with batched sigma-point propagation (paper eq. 32-47)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.linalg.blas import dtrmm

from brakethermo.errors import ConfigError
from brakethermo.estimation._forward import (
    Backend,
    BatchedFilter,
    BatchedFunction,
    KernelSetup,
    MatrixOrCallable,
    Moments,
    Predictor,
    check_backend,
)
from brakethermo.estimation._forward import (
    as_kernel_array as _c,
)
from brakethermo.estimation.results import FilterResult
from brakethermo.estimation.sigma_points import MerweWeights, merwe_weights, sigma_points

Array = NDArray[np.float64]
CompiledSteps = Callable[..., None]  # the model fused into the step loop: UKF ``steps``
STEPS_PER_CALL = 256  # steps of one compiled call: a stop request waits at most this long


class UnscentedKalmanFilter(BatchedFilter[MerweWeights]):
    """UKF over a batched process model; every sigma set goes through ONE model call.

    Parameters
    ----------
    f : callable ``f(X (B, n), k) -> (B, n)`` — advances B states from step k to k+1.
    Q : ndarray (n, n) or callable ``Q(k)`` — process-noise covariance of the step
        k -> k+1, in squared state units.
    R : ndarray (m, m) or callable ``R(k)`` — measurement-noise covariance at step k.
    H : ndarray (m, n) or callable ``H(k)``, optional — linear measurement y = H x + r.
        The update is then the exact linear one (eq. 28-31 with the unscented prior),
        without a second sigma set.
    h : callable ``h(X (B, n), k) -> (B, m)``, optional — nonlinear batched measurement;
        the prior is redrawn as sigma points (eq. 38-44), as filterpy does.
    alpha, beta, kappa : float — Merwe scaling parameters.
    gate : float, optional — reject a measurement whose NIS exceeds the chi-square
        quantile of this probability (e.g. 0.9999); ``None`` uses every measurement.
    eig_floor : float — absolute eigenvalue floor of covariance repairs, squared state units.
    steps : callable, optional — ``f`` and ``Q`` compiled into the kernel's step loop:
        ``steps(k0, k1, offset, work, W, par, thr, H, R, y, M, *stacks)`` runs steps
        ``k0 .. k1 - 1`` with the model at step ``k + offset`` and :func:`_kernels.ukf_step`
        (e.g. :meth:`DiscStateSpace.compiled_steps`). The numba backend then calls it once
        per :data:`STEPS_PER_CALL` steps instead of ``f`` and ``Q`` every step (a constant
        H and R only); it must compute what ``f`` and ``Q`` do.
    backend : {"auto", "numba", "numpy"} — "numba" runs all per-step filter arithmetic
        in one compiled kernel around the model call (linear H only); "numpy" uses
        BLAS-backed numpy. "auto" takes numba for a linear H and n <= 64 (measured faster
        there: Python overhead dominates small n), numpy above.

    Notes
    -----
    Exactly one of ``H`` and ``h`` must be given. The model ``f`` carries augmented
    random-walk parameters through unchanged (see :func:`augment_random_walk`).
    """

    _moments_need_factor = True

    def __init__(
        self,
        f: BatchedFunction,
        Q: MatrixOrCallable,
        R: MatrixOrCallable,
        *,
        H: MatrixOrCallable | None = None,
        h: BatchedFunction | None = None,
        alpha: float = 0.1,
        beta: float = 2.0,
        kappa: float = 0.0,
        gate: float | None = None,
        eig_floor: float = 1e-12,
        backend: Backend = "auto",
        steps: CompiledSteps | None = None,
    ) -> None:
        check_backend(backend, h)
        if (H is None) == (h is None):
            raise ConfigError("give exactly one measurement model: a matrix H or a function h")
        if gate is not None and not 0.0 < gate < 1.0:
            raise ConfigError(f"gate is a probability in (0, 1), got {gate}")
        self.f = f
        self.Q = Q
        self.R = R
        self.H = H
        self.h = h
        self.alpha, self.beta, self.kappa = alpha, beta, kappa
        self.gate = gate
        self.eig_floor = eig_floor
        self.backend = backend
        self.steps = steps

    def weights(self, n: int) -> MerweWeights:
        """Sigma-point weights for an ``n``-dimensional state."""
        return merwe_weights(n, self.alpha, self.beta, self.kappa)

    def _setup(self, n: int) -> MerweWeights:
        """The sigma-point weights, the first thing a run checks."""
        return self.weights(n)

    def _steps(
        self, w: MerweWeights, Q_of: Callable[[int], Array]
    ) -> tuple[Predictor, Moments | None]:
        """The unscented prediction and, with ``h``, the unscented measurement moments."""
        predict = _sigma_predictor(self.f, Q_of, w)
        return predict, None if self.h is None else _sigma_moments(self.h, w)

    def _run_compiled(
        self, w: MerweWeights, x0: Array, P0: Array, y: Array, ks: KernelSetup
    ) -> FilterResult:
        """The forward pass with :func:`_kernels.ukf_step` (same results as numpy)."""
        from brakethermo.estimation import _kernels

        K = y.shape[0]
        n = x0.shape[0]
        B = 2 * n + 1
        work = np.zeros((B + 2 * n + 1, n))  # [X; P; L; x], see _kernels._views
        X, P = work[:B], work[B : B + n]
        P[:] = P0
        work[B + 2 * n] = x0
        W = np.stack([w.Wm, w.Wc])
        par = np.array([w.c, self.eig_floor])
        f, M, thr, tail = self.f, ks.out.M, ks.thr, ks.tail
        ks.first(_kernels.ukf_first, work, par, y)
        step = _kernels.ukf_step
        Q_of, H_of, R_of, Qc, Hc, Rc = ks.Q_of, ks.H_of, ks.R_of, ks.Qc, ks.Hc, ks.Rc
        if self.steps is not None and Hc is not None and Rc is not None:
            for k0 in range(0, K - 1, STEPS_PER_CALL):
                self.steps(k0, min(k0 + STEPS_PER_CALL, K - 1), 0, work, W, par, thr, Hc, Rc,
                           y, M, *tail)
            return ks.result(P)
        for k in range(K - 1):
            Xf = f(X, k)  # eq. 35, all sigma points in one call
            if Xf.shape != X.shape:
                raise ConfigError(f"model f returned shape {Xf.shape}, expected {X.shape}")
            if Xf.dtype != np.float64 or not Xf.flags.c_contiguous:
                Xf = _c(Xf)
            step(
                k, Xf, work, W, par, thr, _c(Q_of(k)) if Qc is None else Qc,
                _c(H_of(k + 1)) if Hc is None else Hc, _c(R_of(k + 1)) if Rc is None else Rc,
                y, M, *tail,
            )  # fmt: skip
        return ks.result(P)


def _sigma_predictor(f: BatchedFunction, Q_of: Callable[[int], Array], w: MerweWeights
                     ) -> Predictor:
    """The unscented prediction (eq. 35-37) and its cross-covariance, over one sigma buffer.

    Parameters
    ----------
    f : callable — the batched process model ``f(X (B, n), k) -> (B, n)``.
    Q_of : callable — process-noise covariance of the step k -> k+1, squared state units.
    w : MerweWeights — sigma-point weights of the state's dimension.
    """
    n = w.n
    Wm, Wc, c = w.Wm, w.Wc, w.c
    X = np.empty((2 * n + 1, n))
    half_over_c = 0.5 / c

    def predict(x: Array, P: Array, L: Array, k: int) -> tuple[Array, Array, Array]:
        sigma_points(x, L, c, out=X)
        Xf = f(X, k)  # eq. 35, all sigma points in one call
        if Xf.shape != X.shape:
            raise ConfigError(f"model f returned shape {Xf.shape}, expected {X.shape}")
        x_p = Wm @ Xf  # eq. 36
        D = Xf - x_p
        D1 = D[1:]
        # eq. 37; the 2n outer sigma points share one weight: one GEMM, then scale
        P_p = D1.T @ D1
        P_p *= Wc[1]
        P_p += Wc[0] * np.outer(D[0], D[0])
        P_p += Q_of(k)
        # C_k = sum_i Wc_i (X_i - x)(Xf_i - x_p)'; X_i - x = +-c L_j and Wc_i = 1/(2c^2);
        # L is triangular: TRMM, half the flops of a general product
        C = dtrmm(half_over_c, L, D[1 : n + 1] - D[n + 1 :], lower=1)
        return x_p, P_p, C

    return predict


def _sigma_moments(h: BatchedFunction, w: MerweWeights) -> Moments:
    """The measurement's unscented moments (eq. 38-44) from the prior, over one buffer.

    Parameters
    ----------
    h : callable — the batched measurement ``h(X (B, n), k) -> (B, m)``.
    w : MerweWeights — sigma-point weights of the state's dimension.
    """
    n = w.n
    Wm, Wc, c = w.Wm, w.Wc, w.c
    Xm = np.empty((2 * n + 1, n))
    half_over_c = 0.5 / c

    def moments(x: Array, P: Array, L: Array, k: int) -> tuple[Array, Array, Array]:
        sigma_points(x, L, c, out=Xm)  # eq. 38-40
        Y = np.asarray(h(Xm, k), dtype=np.float64)  # eq. 41
        mu = Wm @ Y  # eq. 42
        DY = Y - mu
        S0 = (DY.T * Wc) @ DY  # eq. 43 without R
        Cxy = L @ (DY[1 : n + 1] - DY[n + 1 :]) * half_over_c  # eq. 44
        return mu, S0, Cxy

    return moments
