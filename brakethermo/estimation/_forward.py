"""The forward filtering loop shared by the sigma-point and extended Kalman filters.

A filter supplies two pieces: ``predict`` (eq. 32-37 for the UKF, 26-27 linearised for
the EKF) returning the prior and the cross-covariance C_k = cov(x_k, x_{k+1}), and,
for a nonlinear measurement, ``moments`` returning the predicted measurement, its
covariance without R and the state-measurement cross-covariance (eq. 41-44). The
update (eq. 45-47, or 28-31 for a linear H), NaN handling, gating, covariance repair,
storage and the smoother's gains are common and live here, with the choice of backend
(:func:`use_numba`) and :class:`BatchedFilter`, the interface both filters share.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Generic, Literal, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_factor, cho_solve
from scipy.linalg.blas import dtrsm
from scipy.special import chdtri  # scipy.stats costs 0.5 s of import

from brakethermo.errors import ConfigError, DataError
from brakethermo.estimation._kernels import chol_downdate
from brakethermo.estimation.covariance import CovarianceGuard, symmetrise
from brakethermo.estimation.results import FilterResult
from brakethermo.estimation.store import gain_dtype, prefault

Array = NDArray[np.float64]
Store = Literal["full", "smoother", "diag"]
MatrixOrCallable = Array | Callable[[int], Array]
STORES = ("full", "smoother", "diag")
_LOG_2PI = math.log(2.0 * math.pi)
# From this state size on, the posterior's Cholesky factor comes from a compiled rank-1
# downdate of the prior's (O(n^2)) instead of a fresh factorisation (O(n^3)); below it
# the call overhead is larger than the saving.
DOWNDATE_MIN_N = 32
MAX_STORE_BYTES = 4 * 2**30
Backend = Literal["auto", "numba", "numpy"]
BACKENDS = ("auto", "numba", "numpy")
NUMBA_MAX_N = 64
BatchedFunction = Callable[[Array, int], Array]


def use_numba(backend: Backend, h: object | None, n: int) -> bool:
    """Whether a filter with this backend, measurement function and state size compiles."""
    if h is not None or backend == "numpy":
        return False
    return backend == "numba" or n <= NUMBA_MAX_N


def check_backend(backend: Backend, h: object | None = None) -> None:
    """Raise ConfigError unless ``backend`` is known and can run with measurement ``h``.

    Parameters
    ----------
    backend : {"auto", "numba", "numpy"} — the backend asked for.
    h : callable, optional — a nonlinear measurement function, which "numba" cannot run.
    """
    if backend not in BACKENDS:
        raise ConfigError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "numba" and h is not None:
        raise ConfigError("the numba backend needs a linear measurement matrix H")


class Predictor(Protocol):
    """x_{k+1}^-, P_{k+1}^-, C_k from the posterior (x_k, P_k = L L')."""

    def __call__(self, x: Array, P: Array, L: Array, k: int) -> tuple[Array, Array, Array]: ...


class Moments(Protocol):
    """mu_k, S_k - R_k, C_xy from the prior (x_k^-, P_k^- = L L')."""

    def __call__(self, x: Array, P: Array, L: Array, k: int) -> tuple[Array, Array, Array]: ...


def as_provider(M: MatrixOrCallable, shape: tuple[int, ...], name: str) -> Callable[[int], Array]:
    """Turn a constant matrix or a callable of the step into a callable of the step."""
    if callable(M):
        return M
    A = np.array(M, dtype=np.float64)
    if A.ndim == 0 and shape == (1, 1):
        A = A.reshape(1, 1)
    if A.shape != shape:
        raise ConfigError(f"{name} must have shape {shape}, got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ConfigError(f"{name} holds non-finite values")
    A.setflags(write=False)
    return lambda k: A


def model_matrices(
    Q: MatrixOrCallable, R: MatrixOrCallable, H: MatrixOrCallable | None, n: int, m: int
) -> tuple[Callable[[int], Array], Callable[[int], Array], Callable[[int], Array] | None]:
    """Q, R and H as callables of the step, shapes and values checked in that order.

    Parameters
    ----------
    Q : ndarray (n, n) or callable — process-noise covariance, squared state units.
    R : ndarray (m, m) or callable — measurement-noise covariance, squared measurement units.
    H : ndarray (m, n) or callable, optional — linear measurement matrix.
    n, m : int — state and measurement sizes.

    Returns
    -------
    Q_of, R_of : callable ``(k) -> ndarray``.
    H_of : callable ``(k) -> ndarray``, or None without ``H``.
    """
    Q_of = as_provider(Q, (n, n), "Q")
    R_of = as_provider(R, (m, m), "R")
    return Q_of, R_of, None if H is None else as_provider(H, (m, n), "H")


def check_prior(x0: Array, P0: Array, y: Array) -> tuple[Array, Array, Array]:
    """Validate and normalise the initial prior and the measurement array."""
    x0 = np.array(x0, dtype=np.float64).reshape(-1)
    n = x0.shape[0]
    P0 = np.array(P0, dtype=np.float64)
    if P0.shape != (n, n):
        raise ConfigError(f"P0 must have shape ({n}, {n}) to match x0, got {P0.shape}")
    if not (np.all(np.isfinite(x0)) and np.all(np.isfinite(P0))):
        raise ConfigError("x0 and P0 must be finite")
    # a private C-ordered writable copy: pandas hands out read-only views, and the
    # compiled kernels would need a separate compilation for each memory layout
    y = np.array(y, dtype=np.float64, order="C")
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[0] < 1:
        raise ConfigError(f"measurements y must have shape (K, m) with K >= 1, got {y.shape}")
    return x0, symmetrise(P0.copy()), y


@dataclass
class Buffers:
    """Preallocated outputs of a forward pass; unused ones are empty arrays.

    The named arrays are views into a few stacks (``st``, ``cov``, ``gs``, ``iv``,
    ``sc``, ``ic``, ``ro``) so the compiled kernels take few arguments: a numba call
    costs ~75 ns per argument, comparable to a whole small-state step.
    """

    st: Array
    cov: Array
    gs: Array
    iv: Array
    sc: Array
    ic: NDArray[np.int64]
    ro: Array
    x_pred: Array
    x_filt: Array
    var_pred: Array
    var_filt: Array
    P_pred: Array
    P_filt: Array
    cross: Array
    G: Array
    Sigma: Array
    innovation: Array
    innovation_var: Array
    nis: Array
    loglik: Array
    n_obs: NDArray[np.int64]
    rejected: NDArray[np.bool_]
    M: Array
    readout: Array
    readout_var: Array
    full: bool
    gains: bool
    store: str

    def result(self, P_last: Array, repair_steps: list[int]) -> FilterResult:
        """Freeze into a FilterResult; arrays not kept by ``store`` become None.

        Raises DataError if the state went non-finite: that only happens when the model
        returned NaN or inf, and a silent NaN track would be worse than a clear stop.
        """
        bad = ~np.isfinite(self.x_filt).all(axis=1)
        if bad.any():
            k = int(np.argmax(bad))
            raise DataError(
                f"the filter state became non-finite at step {k}: the model returned NaN "
                "or inf; check its inputs around that step"
            )
        has_ro = self.M.shape[0] > 0
        return FilterResult(
            x_pred=self.x_pred,
            x_filt=self.x_filt,
            var_pred=self.var_pred,
            var_filt=self.var_filt,
            P_pred=self.P_pred if self.full else None,
            P_filt=self.P_filt if self.full else None,
            cross=self.cross if self.full else None,
            G=self.G if self.gains else None,
            Sigma=self.Sigma if self.gains else None,
            P_last=P_last.copy(),
            innovation=self.innovation,
            innovation_var=self.innovation_var,
            nis=self.nis,
            loglik=self.loglik,
            n_obs=self.n_obs,
            rejected=self.rejected,
            readout=self.readout if has_ro else None,
            readout_var=self.readout_var if has_ro else None,
            n_repairs=len(repair_steps),
            repair_steps=tuple(repair_steps),
            store=self.store,
        )


def readout_matrix(readout: Array | None, n: int) -> Array:
    """The readout matrix M (p, n); (0, n) when there is none."""
    if readout is None:
        return np.zeros((0, n))
    M = np.array(np.atleast_2d(readout), dtype=np.float64, order="C")
    if M.ndim != 2 or M.shape[1] != n:
        raise ConfigError(f"readout matrix must have {n} columns, got shape {M.shape}")
    return M


def allocate(
    K: int,
    n: int,
    m: int,
    readout: Array | None,
    store: Store,
    store_dtype: type[np.floating] | np.dtype | None,
) -> Buffers:
    """Allocate the outputs for K steps; covariance stacks only as ``store`` needs."""
    if store not in STORES:
        raise ConfigError(f"store must be one of {STORES}, got {store!r}")
    store_dtype = gain_dtype(n, store_dtype)
    full = store == "full"
    gains = store in ("full", "smoother")
    stacks = (3 * 8 if full else 0) + (2 * np.dtype(store_dtype).itemsize if gains else 0)
    need = stacks * K * n * n
    if need > MAX_STORE_BYTES:
        raise ConfigError(
            f"store={store!r} would hold {need / 2**30:.1f} GiB of covariances for {K} steps "
            f"at state size {n} (limit {MAX_STORE_BYTES / 2**30:.0f} GiB); use store='diag' "
            "(filter only) or smooth in windows (urts.urts_smooth_windowed)"
        )
    nf = K if full else 0
    ngain = max(K - 1, 0) if gains else 0
    M = readout_matrix(readout, n)
    p = M.shape[0]
    st = np.empty((4, K, n))
    cov = np.empty((3, nf, n, n))
    gs = np.empty((2, ngain, n, n), dtype=store_dtype)
    prefault(gs)
    iv = np.full((2, K, m), np.nan)
    sc = np.zeros((2, K))
    sc[0] = np.nan
    ic = np.zeros((2, K), dtype=np.int64)
    ro = np.empty((2, K if p else 0, p))
    return Buffers(
        st=st,
        cov=cov,
        gs=gs,
        iv=iv,
        sc=sc,
        ic=ic,
        ro=ro,
        x_pred=st[0],
        var_pred=st[1],
        x_filt=st[2],
        var_filt=st[3],
        P_pred=cov[0],
        P_filt=cov[1],
        cross=cov[2, : max(nf - 1, 0)],
        G=gs[0],
        Sigma=gs[1],
        innovation=iv[0],
        innovation_var=iv[1],
        nis=sc[0],
        loglik=sc[1],
        n_obs=ic[0],
        rejected=np.zeros(K, dtype=bool),
        M=M,
        readout=ro[0],
        readout_var=ro[1],
        full=full,
        gains=gains,
        store=store,
    )


def gate_thresholds(gate: float | None, m: int) -> Array:
    """Chi-square NIS thresholds indexed by the number of used components; 0 = no gate."""
    thr = np.zeros(m + 1)
    if gate is not None:
        thr[1:] = chdtri(np.arange(1, m + 1), 1.0 - gate)  # chi2.ppf(gate, dof)
    return thr


def as_kernel_array(A: Array) -> Array:
    """C-contiguous writable float64 array for the kernels (one compiled signature)."""
    return np.require(A, dtype=np.float64, requirements=("C", "W"))


@dataclass(frozen=True)
class KernelSetup:
    """What the compiled forward passes of the UKF and the EKF set up alike.

    Constant Q, H and R are converted to kernel arrays once (``Qc``, ``Hc``, ``Rc``); for a
    callable one that field is None and ``Q_of(k)`` etc. are asked every step.
    """

    out: Buffers
    thr: Array
    Q_of: Callable[[int], Array]
    H_of: Callable[[int], Array]
    R_of: Callable[[int], Array]
    Qc: Array | None
    Hc: Array | None
    Rc: Array | None

    @property
    def tail(self) -> tuple[Array, ...]:
        """The output stacks every kernel step takes last."""
        o = self.out
        return (o.st, o.cov, o.gs, o.iv, o.sc, o.ic, o.rejected, o.ro)

    def first(self, kernel: Callable[..., None], work: Array, par: Array, y: Array) -> None:
        """Step 0 (record the prior, update with y[0]) with ``kernel``: ukf_first or ekf_first."""
        o = self.out
        kernel(work, par, self.thr, as_kernel_array(self.H_of(0)),
               as_kernel_array(self.R_of(0)), y, o.M, o.st, o.cov, o.iv, o.sc, o.ic,
               o.rejected, o.ro)  # fmt: skip

    def result(self, P_last: Array) -> FilterResult:
        """The result, with the steps at which the kernels repaired a covariance."""
        repairs = self.out.ic[1]
        return self.out.result(P_last, np.repeat(np.arange(repairs.shape[0]), repairs).tolist())


def kernel_setup(
    Q: MatrixOrCallable,
    H: MatrixOrCallable,
    R: MatrixOrCallable,
    gate: float | None,
    y: Array,
    n: int,
    readout: Array | None,
    store: Store,
    store_dtype: type[np.floating] | None,
) -> KernelSetup:
    """Buffers, gate thresholds and Q, H, R for a compiled forward pass over ``y`` (K, m)."""
    K, m = y.shape
    out = allocate(K, n, m, readout, store, store_dtype)
    Q_of, R_of, H_of = model_matrices(Q, R, H, n, m)
    assert H_of is not None  # a compiled pass has a linear H (use_numba)
    # constant matrices are converted once; callables are asked every step
    return KernelSetup(
        out,
        gate_thresholds(gate, m),
        Q_of,
        H_of,
        R_of,
        None if callable(Q) else as_kernel_array(Q_of(0)),
        None if callable(H) else as_kernel_array(H_of(0)),
        None if callable(R) else as_kernel_array(R_of(0)),
    )


def _measurement_update(
    out: Buffers, k: int, x: Array, P: Array, L: Array | None, y: Array, finite: Array,
    moments: Moments | None, H_of: Callable[[int], Array] | None, R_of: Callable[[int], Array],
    thresholds: Array, guard: CovarianceGuard,
) -> tuple[Array, Array, Array | None, bool]:
    """The update of step ``k`` with its finite readings (eq. 44-47), innovations and
    scores written into ``out``. Returns the posterior, the vector ``v`` of a rank-1
    update (``P_post = P - v v'``, else None) and whether the update was applied."""
    v_down, updated = None, False
    R = R_of(k)
    if moments is None:
        assert H_of is not None  # a linear update has H (check_model ensured it)
        H = H_of(k)
        PHt = P @ H.T
        mu, S0, Cxy = H @ x, H @ PHt, PHt
    else:
        mu, S0, Cxy = moments(x, P, L, k)
    if finite[k].all():
        idx = None
        yk = y[k]
    else:
        idx = np.flatnonzero(finite[k])
        yk = y[k, idx]
        mu, S0, Cxy, R = mu[idx], S0[np.ix_(idx, idx)], Cxy[:, idx], R[np.ix_(idx, idx)]
    nu = yk - mu
    S = S0 + R
    mk = nu.shape[0]
    if mk == 1:
        s = S[0, 0]
        if not s > 0.0:
            S = guard.repair(S, k)
            s = S[0, 0]
        Kg = Cxy / s
        nis_k = nu[0] * nu[0] / s
        logdet = math.log(s)
    else:
        try:
            cf = cho_factor(S, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            S = guard.repair(S, k)
            cf = cho_factor(S, lower=True, check_finite=False)
        Kg = cho_solve(cf, Cxy.T, check_finite=False).T  # eq. 45, no inverse
        nis_k = float(nu @ cho_solve(cf, nu, check_finite=False))
        logdet = 2.0 * float(np.sum(np.log(np.diagonal(cf[0]))))
    if idx is None:
        out.innovation[k] = nu
        out.innovation_var[k] = np.diagonal(S)
    else:
        out.innovation[k, idx] = nu
        out.innovation_var[k, idx] = np.diagonal(S)
    if thresholds[mk] > 0.0 and nis_k > thresholds[mk]:
        out.rejected[k] = True
    else:
        x = x + Kg @ nu  # eq. 46
        updated = True
        if mk == 1:
            # eq. 47 as P - v v', v = C_xy / sqrt(S): symmetric as it stands
            v_down = Cxy[:, 0] / math.sqrt(s)
            P = P - np.outer(v_down, v_down)
        else:
            P = symmetrise(P - Kg @ Cxy.T)  # eq. 47, K S K' = K C_xy'
        out.n_obs[k] = mk
        out.nis[k] = nis_k
        out.loglik[k] = -0.5 * (nis_k + logdet + mk * _LOG_2PI)
    return x, P, v_down, updated


def run_forward(
    predict: Predictor,
    moments: Moments | None,
    H_of: Callable[[int], Array] | None,
    R_of: Callable[[int], Array],
    x0: Array,
    P0: Array,
    y: Array,
    *,
    store: Store,
    store_dtype: type[np.floating] | np.dtype | None,
    readout: Array | None,
    gate: float | None,
    guard: CovarianceGuard,
    needs_prior_factor: bool,
) -> FilterResult:
    """Run the filter over all steps; see the filter classes for the meaning of arguments."""
    x0, P0, y = check_prior(x0, P0, y)
    K, m = y.shape
    n = x0.shape[0]
    out = allocate(K, n, m, readout, store, store_dtype)
    M, has_ro, full, gains = out.M, out.M.shape[0] > 0, out.full, out.gains
    finite = np.isfinite(y)
    any_obs = finite.any(axis=1)
    thresholds = gate_thresholds(gate, m)
    # the prior's factor is only needed by a sigma-point measurement update at step 0
    x, P, L = x0, P0, None
    if needs_prior_factor:
        L, P = guard.cholesky(P0, 0)
    # the prior's factor, when the previous step computed it; lets a rank-1 update
    # downdate it into the posterior's (see chol_downdate)
    L_prior = L
    downdate = moments is None and n >= DOWNDATE_MIN_N

    for k in range(K):
        out.x_pred[k] = x
        out.var_pred[k] = np.diagonal(P)
        if full:
            out.P_pred[k] = P
        x, P, v_down, updated = (
            _measurement_update(out, k, x, P, L, y, finite, moments, H_of, R_of, thresholds,
                                guard) if any_obs[k] else (x, P, None, False))
        if k < K - 1:
            L = None
            if downdate and L_prior is not None:
                if not updated:
                    L = L_prior
                elif v_down is not None:
                    L = L_prior.copy()
                    if not chol_downdate(L, v_down):
                        L = None
            if L is None:
                L, P = guard.cholesky(P, k)  # the posterior as factored is the one stored
        out.x_filt[k] = x
        out.var_filt[k] = np.diagonal(P)
        if full:
            out.P_filt[k] = P
        if has_ro:
            out.readout[k] = M @ x
            out.readout_var[k] = np.einsum("ij,jk,ik->i", M, P, M)
        if k == K - 1:
            break
        x_next, P_next, C = predict(x, P, L, k)
        P_next = symmetrise(P_next)
        if full:
            out.cross[k] = C
        if gains or needs_prior_factor:
            L_next, P_next = guard.cholesky(P_next, k + 1)
        if gains:
            # G_k = C_k (P_{k+1}^-)^-1 = Z' L^-1 with Z = L^-1 C_k' (P_{k+1}^- = L L'), and
            # G_k P_{k+1}^- G_k' = Z'Z: two triangular solves and a symmetric product
            Z = dtrsm(1.0, L_next, C.T, lower=1)
            out.G[k] = dtrsm(1.0, L_next, Z, lower=1, trans_a=1).T
            # P_k - G_k P_{k+1}^- G_k'; symmetric as it stands (Z'Z is a SYRK)
            out.Sigma[k] = P - Z.T @ Z
        L = L_next if (gains or needs_prior_factor) else None
        L_prior = L
        x, P = x_next, P_next

    return out.result(P, guard.repair_steps)


Setup = TypeVar("Setup")


class BatchedFilter(ABC, Generic[Setup]):
    """A Kalman filter over a batched process model: the interface the UKF and the EKF share.

    The attributes are the constructor arguments of :class:`UnscentedKalmanFilter` and
    :class:`ExtendedKalmanFilter` of the same names. A subclass supplies what differs:
    what it derives from the state size before anything else (:meth:`_setup`, ``Setup``:
    the UKF's sigma-point weights), the prediction and measurement moments of the numpy
    pass (:meth:`_steps`) and the compiled pass (:meth:`_run_compiled`).
    """

    # whether the measurement moments need the prior's Cholesky factor (sigma points)
    _moments_need_factor: ClassVar[bool]
    f: BatchedFunction
    Q: MatrixOrCallable
    R: MatrixOrCallable
    H: MatrixOrCallable | None
    h: BatchedFunction | None
    gate: float | None
    eig_floor: float
    backend: Backend

    def run(
        self,
        x0: Array,
        P0: Array,
        y: Array,
        *,
        store: Store = "smoother",
        store_dtype: type[np.floating] | None = None,
        readout: Array | None = None,
    ) -> FilterResult:
        """Filter the measurements ``y``.

        Parameters
        ----------
        x0 : ndarray (n,) — prior mean of the state at step 0 (before y[0]).
        P0 : ndarray (n, n) — prior covariance at step 0.
        y : ndarray (K, m) — measurements; NaN marks a missing component, an all-NaN
            row is a predict-only step.
        store : {"full", "smoother", "diag"} — "full" keeps P_pred, P_filt, cross and
            the gains (K n^2 x 5 floats); "smoother" keeps only the gains and Sigma the
            RTS smoother needs (K n^2 x 2); "diag" keeps variances only (no smoother).
        store_dtype : numpy float type, optional — dtype of the stored gains and Sigma;
            default float64 below n = 24 and float32 from there (halves the smoother's
            memory at ~1e-7 relative precision).
        readout : ndarray (p, n), optional — matrix M whose M x and diag(M P M') are
            recorded each step (e.g. interpolation to sensor radii).

        Returns
        -------
        FilterResult
        """
        x0, P0, y = check_prior(x0, P0, y)
        n, m = x0.shape[0], y.shape[1]
        setup = self._setup(n)
        if use_numba(self.backend, self.h, n):
            ks = kernel_setup(
                self.Q, self.H, self.R, self.gate, y, n, readout, store, store_dtype  # type: ignore[arg-type]
            )
            return self._run_compiled(setup, x0, P0, y, ks)
        Q_of, R_of, H_of = model_matrices(self.Q, self.R, self.H, n, m)
        predict, moments = self._steps(setup, Q_of)
        return run_forward(
            predict,
            moments,
            H_of,
            R_of,
            x0,
            P0,
            y,
            store=store,
            store_dtype=store_dtype,
            readout=readout,
            gate=self.gate,
            guard=CovarianceGuard(abs_floor=self.eig_floor),
            needs_prior_factor=moments is not None and self._moments_need_factor,
        )

    @abstractmethod
    def _setup(self, n: int) -> Setup:
        """What both passes derive from the state size ``n``, checked before the matrices."""

    @abstractmethod
    def _steps(
        self, setup: Setup, Q_of: Callable[[int], Array]
    ) -> tuple[Predictor, Moments | None]:
        """The prediction and, with ``h``, the measurement moments of the numpy pass."""

    @abstractmethod
    def _run_compiled(
        self, setup: Setup, x0: Array, P0: Array, y: Array, ks: KernelSetup
    ) -> FilterResult:
        """The forward pass with the compiled per-step kernels (same results as numpy)."""
