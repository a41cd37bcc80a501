"""Extended Kalman filter over the same batched model interface, for comparison."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

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

Array = NDArray[np.float64]
Jacobian = Callable[[Array, int], Array]

_FD_REL_STEP = 1.5e-8  # ~sqrt(machine epsilon): forward-difference optimum


def batched_jacobian(g: BatchedFunction, x: Array, k: int) -> tuple[Array, Array]:
    """Value and forward-difference Jacobian of a batched function in ONE call.

    Parameters
    ----------
    g : callable ``g(X (B, n), k) -> (B, p)``.
    x : ndarray (n,) — linearisation point.
    k : int — step index passed to ``g``.

    Returns
    -------
    gx : ndarray (p,) — g(x).
    J : ndarray (p, n) — dg/dx at x.
    """
    n = x.shape[0]
    eps = _FD_REL_STEP * np.maximum(np.abs(x), 1.0)
    X = np.empty((n + 1, n))
    X[:] = x
    X[1:] += np.diag(eps)
    GX = np.asarray(g(X, k), dtype=np.float64)
    return GX[0], ((GX[1:] - GX[0]) / eps[:, None]).T


class ExtendedKalmanFilter(BatchedFilter[None]):
    """EKF with the UKF's interface: batched ``f``, linear ``H`` or batched ``h``.

    Parameters
    ----------
    f : callable ``f(X (B, n), k) -> (B, n)`` — batched transition from step k to k+1.
    Q : ndarray (n, n) or callable ``Q(k)`` — process-noise covariance of step k -> k+1.
    R : ndarray (m, m) or callable ``R(k)`` — measurement-noise covariance at step k.
    H : ndarray (m, n) or callable ``H(k)``, optional — linear measurement matrix.
    h : callable ``h(X (B, n), k) -> (B, m)``, optional — nonlinear batched measurement.
    F_jac : callable ``F_jac(x (n,), k) -> (n, n)``, optional — analytic transition
        Jacobian; without it the Jacobian is a forward difference from one batched
        call of ``f`` on n + 1 states.
    gate : float, optional — chi-square gate probability for outlier rejection.
    eig_floor : float — absolute eigenvalue floor of covariance repairs.
    pseudo_noise : callable ``pseudo_noise(x (n,), P (n, n), k) -> (m, m)``, optional —
        measurement covariance added to R at step k as a function of the prior, e.g. the
        second-order terms of the linearisation of ``h`` (with ``h`` only).
    backend : {"auto", "numba", "numpy"} — as the UKF's: "numba" runs all per-step
        filter arithmetic (Jacobian from the batched call, eq. 26-31, the smoother's
        gains) in one compiled kernel around the model call (linear H only); "auto"
        takes it for a linear H and n <= 64.
    """

    _moments_need_factor = False

    def __init__(
        self,
        f: BatchedFunction,
        Q: MatrixOrCallable,
        R: MatrixOrCallable,
        *,
        H: MatrixOrCallable | None = None,
        h: BatchedFunction | None = None,
        F_jac: Jacobian | None = None,
        gate: float | None = None,
        eig_floor: float = 1e-12,
        pseudo_noise: Callable[[Array, Array, int], Array] | None = None,
        backend: Backend = "auto",
    ) -> None:
        if (H is None) == (h is None):
            raise ConfigError("give exactly one measurement model: a matrix H or a function h")
        if pseudo_noise is not None and h is None:
            raise ConfigError("pseudo_noise needs a nonlinear measurement function h")
        check_backend(backend, h)
        self.backend = backend
        if gate is not None and not 0.0 < gate < 1.0:
            raise ConfigError(f"gate is a probability in (0, 1), got {gate}")
        self.f, self.Q, self.R, self.H, self.h, self.F_jac = f, Q, R, H, h, F_jac
        self.gate = gate
        self.eig_floor = eig_floor
        self.pseudo_noise = pseudo_noise

    def _setup(self, n: int) -> None:
        """Nothing: the EKF has no constants of the state size."""

    def _steps(self, setup: None, Q_of: Callable[[int], Array]) -> tuple[Predictor, Moments | None]:
        """The linearised prediction and, with ``h``, the linearised measurement moments."""
        f, h, F_jac, pseudo = self.f, self.h, self.F_jac, self.pseudo_noise

        def predict(x: Array, P: Array, L: Array, k: int) -> tuple[Array, Array, Array]:
            if F_jac is None:
                x_p, F = batched_jacobian(f, x, k)
            else:
                x_p, F = np.asarray(f(x[None, :], k), dtype=np.float64)[0], F_jac(x, k)
            C = P @ F.T  # cov(x_k, x_{k+1}) of the linearised model
            return x_p, F @ C + Q_of(k), C  # eq. 26-27 linearised

        def moments(x: Array, P: Array, L: Array, k: int) -> tuple[Array, Array, Array]:
            mu, Hj = batched_jacobian(h, x, k)
            Cxy = P @ Hj.T
            S0 = Hj @ Cxy
            if pseudo is not None:
                S0 = S0 + pseudo(x, P, k)
            return mu, S0, Cxy

        return predict, None if h is None else moments

    def _run_compiled(
        self, setup: None, x0: Array, P0: Array, y: Array, ks: KernelSetup
    ) -> FilterResult:
        """The forward pass with :func:`_kernels.ekf_step` (same results as numpy)."""
        from brakethermo.estimation import _kernels

        K = y.shape[0]
        n = x0.shape[0]
        work = np.zeros((3 * n + 3, n))  # [X (n + 1); P; L; x; eps], see _kernels._ekf_views
        X, P, x = work[: n + 1], work[n + 1 : 2 * n + 1], work[3 * n + 1]
        P[:] = P0
        x[:] = x0
        par = np.array([_FD_REL_STEP, self.eig_floor])
        f, F_jac, M, thr, tail = self.f, self.F_jac, ks.out.M, ks.thr, ks.tail
        ks.first(_kernels.ekf_first, work, par, y)
        step = _kernels.ekf_step
        no_jac = np.empty((0, n))
        Q_of, H_of, R_of, Qc, Hc, Rc = ks.Q_of, ks.H_of, ks.R_of, ks.Qc, ks.Hc, ks.Rc
        for k in range(K - 1):
            # the n + 1 points x, x + eps_j e_j in ONE call, or f(x) and the analytic F
            Xk = X if F_jac is None else X[:1]
            GX = f(Xk, k)
            if GX.shape != Xk.shape:
                raise ConfigError(f"model f returned shape {GX.shape}, expected {Xk.shape}")
            Fj = no_jac if F_jac is None else _c(F_jac(x.copy(), k))
            step(
                k, _c(GX), Fj, work, par, thr, _c(Q_of(k)) if Qc is None else Qc,
                _c(H_of(k + 1)) if Hc is None else Hc, _c(R_of(k + 1)) if Rc is None else Rc,
                y, M, *tail,
            )  # fmt: skip
        return ks.result(P)
