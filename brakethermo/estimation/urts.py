"""Rauch-Tung-Striebel backward pass for sigma-point and extended Kalman filters.

The forward pass stores, per step, the gain G_k = C_k (P_{k+1}^-)^-1 and
Sigma_k = P_k - G_k P_{k+1}^- G_k', with C_k the cross-covariance of the prediction
(from the UKF's propagated sigma set, Särkkä's unscented RTS smoother). The backward
recursion

    m_k^s = m_k + G_k (m_{k+1}^s - m_{k+1}^-)
    P_k^s = Sigma_k + G_k P_{k+1}^s G_k'

therefore needs no model re-evaluation and no matrix inversion.

The gains take K n^2 x 2 floats: 34 GB for a 29 000-step race at n = 600 (150 nodes x
4 layers). :func:`urts_smooth_windowed` bounds that whatever the mesh and session
length by checkpointing: a first forward pass keeps only the prior (x, P) at the start
of each window (on disk); the backward pass then goes window by window from the last,
re-running the forward pass of one window from its checkpoint to regenerate its gains
and handing the smoothed (x, P) of the window's first step to the window before. The
re-run repeats the same arithmetic, so the answer is the whole-session smoother's, to
rounding. The re-runs of different windows are independent and run in parallel.
"""


from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import nullcontext
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from threadpoolctl import threadpool_limits

from brakethermo.errors import ConfigError
from brakethermo.estimation._forward import (
    Backend,
    MatrixOrCallable,
    check_backend,
    check_prior,
    readout_matrix,
    use_numba,
)
from brakethermo.estimation.covariance import symmetrise
from brakethermo.estimation.results import (
    FilterResult,
    ForwardTrace,
    SmootherResult,
    WindowedSmootherResult,
)
from brakethermo.estimation.store import gain_dtype
from brakethermo.estimation.ukf import UnscentedKalmanFilter

Array = NDArray[np.float64]


def urts_smooth(
    result: FilterResult,
    *,
    store: Literal["full", "diag"] = "diag",
    readout: Array | None = None,
    backend: Backend = "auto",
    start: tuple[Array, Array] | None = None,
) -> SmootherResult:
    """Smooth a forward pass run with ``store="full"`` or ``store="smoother"``.

    Parameters
    ----------
    result : FilterResult — output of UnscentedKalmanFilter.run or ExtendedKalmanFilter.run.
    store : {"full", "diag"} — keep all smoothed covariances (K, n, n) or their diagonals.
    readout : ndarray (p, n), optional — matrix M whose M x^s and diag(M P^s M') are
        recorded (e.g. interpolation to sensor radii).
    backend : {"auto", "numba", "numpy"} — compiled loop or numpy; "auto" as the UKF.
    start : (ndarray (n,), ndarray (n, n)), optional — smoothed mean and covariance of
        the last step when ``result`` is a window of a longer run (the later window's
        hand-over); default: the last step's filtered ones (the run ends there).

    Returns
    -------
    SmootherResult — with ``P_first``, the smoothed covariance of step 0.
    """
    if result.G is None or result.Sigma is None:
        raise ConfigError(
            "the smoother needs the forward pass run with store='smoother' or 'full', "
            f"got store={result.store!r}"
        )
    if store not in ("full", "diag"):
        raise ConfigError(f"smoother store must be 'full' or 'diag', got {store!r}")
    K, n = result.x_filt.shape
    x_last, P_last = (result.x_filt[K - 1], result.P_last) if start is None else start
    M = None if readout is None else readout_matrix(readout, n)
    x_s = np.empty((K, n))
    var_s = np.empty((K, n))
    P_all = np.empty((K, n, n)) if store == "full" else None
    ro = None if M is None else np.empty((K, M.shape[0]))
    ro_var = None if M is None else np.empty((K, M.shape[0]))

    x_filt, x_pred, G_all, Sigma_all = result.x_filt, result.x_pred, result.G, result.Sigma
    check_backend(backend)
    if use_numba(backend, None, n):
        from brakethermo.estimation._kernels import rts_backward

        P_first = np.empty((n, n))
        rts_backward(
            x_filt, x_pred, G_all, Sigma_all, np.array(x_last, dtype=np.float64),
            np.array(P_last, dtype=np.float64), x_s, var_s,
            np.empty((0, n, n)) if P_all is None else P_all, P_all is not None,
            np.zeros((0, n)) if M is None else M, np.empty((K, 0)) if ro is None else ro,
            np.empty((K, 0)) if ro_var is None else ro_var, P_first,
        )  # fmt: skip
        return SmootherResult(
            x_smooth=x_s, var_smooth=var_s, P_smooth=P_all, readout=ro, readout_var=ro_var,
            P_first=P_first,
        )  # fmt: skip
    xs = np.array(x_last, dtype=np.float64)
    Ps = np.array(P_last, dtype=np.float64)
    for k in range(K - 1, -1, -1):
        if k < K - 1:
            G = G_all[k].astype(np.float64, copy=False)
            xs = x_filt[k] + G @ (xs - x_pred[k + 1])
            Ps = symmetrise(Sigma_all[k] + G @ Ps @ G.T)
        x_s[k] = xs
        var_s[k] = np.diagonal(Ps)
        if P_all is not None:
            P_all[k] = Ps
        if M is not None:
            ro[k] = M @ xs
            ro_var[k] = np.einsum("ij,jk,ik->i", M, Ps, M)
    return SmootherResult(
        x_smooth=x_s, var_smooth=var_s, P_smooth=P_all, readout=ro, readout_var=ro_var,
        P_first=Ps,
    )


def default_store_budget(share: int = 1) -> int:
    """Bytes of gains held at one time by default: an eighth of the memory this process may
    use (the machine's, or its container's limit) over ``share`` processes running side by
    side (a batch's workers), between 512 MiB and 2 GiB.

    A window that does not fit is re-run by the backward pass, a second forward pass over
    it: a 25-lap race with k_z switched on (thin-skin layering, 63 states, float32,
    0.9 GB of gains) smoothed in 5.0 s in two windows of 512 MiB, 1.1 s in one (peak
    memory 0.93 -> 1.35 GB, the whole estimate 16.2 -> 13.2 s). 2 GiB holds about 55 laps
    of it in one window; the floor keeps the default model's 25-lap race (~0.4 GB) in one
    on any machine, and finer meshes are still cut into windows.
    """
    ram = memory_bytes()
    return int(min(max(ram // (8 * max(share, 1)), 512 * 2**20), 2 * 2**30))


def memory_bytes() -> int:
    """The memory this process may use: the machine's, or its container's limit (cgroup
    v2) when lower; 0 when neither can be read."""
    try:
        ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # no sysconf (Windows) or no such name
        ram = 0
    try:  # "max" when the container sets no limit
        ram = min(ram, int(Path("/sys/fs/cgroup/memory.max").read_text()))
    except (OSError, ValueError):
        pass
    return max(ram, 0)


def share_store_budget(share: int) -> None:
    """Set this process's default to its part of the budget (a batch worker's initializer)."""
    global DEFAULT_MAX_STORE_BYTES
    DEFAULT_MAX_STORE_BYTES = default_store_budget(share)


DEFAULT_MAX_STORE_BYTES = default_store_budget()


def _from_step(a: int, fn: Callable | None) -> Callable | None:
    """``fn`` with its step argument counted from ``a`` (last argument is the step)."""
    if fn is None or a == 0:
        return fn
    return lambda *args: fn(*args[:-1], args[-1] + a)


def _window_filter(ukf: UnscentedKalmanFilter, a: int) -> UnscentedKalmanFilter:
    """The same filter with its steps counted from step ``a`` of the session."""

    def shift(M: MatrixOrCallable | None) -> MatrixOrCallable | None:
        return _from_step(a, M) if callable(M) else M

    return UnscentedKalmanFilter(
        _from_step(a, ukf.f), shift(ukf.Q), shift(ukf.R), H=shift(ukf.H), h=_from_step(a, ukf.h),
        alpha=ukf.alpha, beta=ukf.beta, kappa=ukf.kappa, gate=ukf.gate,
        eig_floor=ukf.eig_floor, backend=ukf.backend, steps=_steps_from(a, ukf.steps),
    )  # fmt: skip


def _steps_from(a: int, steps: Callable | None) -> Callable | None:
    """Compiled ``steps`` of a UKF with the model's steps counted from ``a``."""
    if steps is None or a == 0:
        return steps
    return lambda k0, k1, offset, *args: steps(k0, k1, offset + a, *args)


def window_steps(
    K: int, n: int, *, itemsize: int, max_store_bytes: int, held: int = 1
) -> int:
    """Steps per window so that ``held`` windows' gains fit ``max_store_bytes``.

    The whole session is one window when its gains fit; otherwise each window holds
    ``max_store_bytes / held`` (at least 2 steps).
    """
    per_step = 2 * itemsize * n * n  # G_k and Sigma_k
    if K * per_step <= max_store_bytes:
        return K
    return max(2, int(max_store_bytes // (held * per_step)))


class _Trace:
    """The forward pass's per-step facts, gathered window by window."""

    def __init__(self, K: int, m: int, p: int) -> None:
        self.innov = np.full((K, m), np.nan)
        self.innov_var = np.full((K, m), np.nan)
        self.nis = np.full(K, np.nan)
        self.loglik = np.zeros(K)
        self.n_obs = np.zeros(K, dtype=np.int64)
        self.rejected = np.zeros(K, dtype=bool)
        self.ro = np.empty((K, p))
        self.ro_var = np.empty((K, p))
        self.repairs: list[int] = []

    def take(self, res: FilterResult, a: int, b: int) -> None:
        """Steps ``[a, b)`` from a window's run (which may hold one step more)."""
        L = b - a
        self.innov[a:b], self.innov_var[a:b] = res.innovation[:L], res.innovation_var[:L]
        self.nis[a:b], self.loglik[a:b] = res.nis[:L], res.loglik[:L]
        self.n_obs[a:b], self.rejected[a:b] = res.n_obs[:L], res.rejected[:L]
        if self.ro.shape[1]:
            self.ro[a:b], self.ro_var[a:b] = res.readout[:L], res.readout_var[:L]
        self.repairs.extend(s + a for s in res.repair_steps)

    def result(self) -> ForwardTrace:
        p = self.ro.shape[1]
        return ForwardTrace(
            innovation=self.innov, innovation_var=self.innov_var, nis=self.nis,
            loglik=self.loglik, n_obs=self.n_obs, rejected=self.rejected,
            readout=self.ro if p else None, readout_var=self.ro_var if p else None,
            n_repairs=len(self.repairs), repair_steps=tuple(self.repairs),
        )


def _backward_pass(
    spans: tuple[tuple[int, int], ...], held_last: list[FilterResult | None],
    rerun: Callable[[int], FilterResult], workers: int, held: int, ro_arg: Array | None,
    backend: Backend, n: int,
) -> tuple[SmootherResult, int]:
    """The RTS pass window by window from the last (``held_last``: its run, in a list
    the pass empties so its gains are freed once smoothed instead of living through the
    whole pass), earlier windows re-run from their checkpoints (by ``workers`` threads
    ahead of the pass); the smoothed result and the most bytes of gains held at once."""
    peak = 0
    K, p = spans[-1][1], 0 if ro_arg is None else ro_arg.shape[0]
    x_s = np.empty((K, n))
    var_s = np.empty((K, n))
    s_ro = np.empty((K, p))
    s_ro_var = np.empty((K, p))
    start: tuple[Array, Array] | None = None
    parallel = workers > 1 and len(spans) > 2
    pool = ThreadPoolExecutor(workers) if parallel else None
    # one BLAS thread per worker: the workers are the parallelism
    limit = threadpool_limits(1) if parallel else nullcontext()
    with limit:
        try:
            for j, res in _backwards(len(spans), held_last, rerun, pool, workers):
                a, b = spans[j]
                L = b - a
                peak = max(peak, _gain_bytes(res) * (held if parallel else 1))
                sm = urts_smooth(res, readout=ro_arg, backend=backend, start=start)
                x_s[a:b], var_s[a:b] = sm.x_smooth[:L], sm.var_smooth[:L]
                if p:
                    s_ro[a:b], s_ro_var[a:b] = sm.readout[:L], sm.readout_var[:L]
                start = (sm.x_smooth[0].copy(), sm.P_first)
                del res, sm
        finally:
            if pool is not None:
                pool.shutdown(cancel_futures=True)
    smoothed = SmootherResult(
        x_smooth=x_s, var_smooth=var_s, P_smooth=None, readout=s_ro if p else None,
        readout_var=s_ro_var if p else None, P_first=None if start is None else start[1],
    )  # fmt: skip
    return smoothed, peak


def _window_runner(ukf: UnscentedKalmanFilter, y: Array, spans: tuple[tuple[int, int], ...],
                   dtype: np.dtype, readout: Array | None
                   ) -> Callable[[int, Array, Array], FilterResult]:
    """The forward run of window ``j`` from its prior ``(x, P)``, with the gains stored.

    Parameters
    ----------
    ukf : UnscentedKalmanFilter — the filter, its steps the session's.
    y : ndarray (K, m) — the session's measurements.
    spans : tuple of (int, int) — each window's steps ``[a, b)``.
    dtype : numpy dtype — of the stored gains and Sigma.
    readout : ndarray (p, n), optional — the readout matrix recorded each step.
    """
    K = y.shape[0]

    def run_window(j: int, x: Array, P: Array) -> FilterResult:
        a, b = spans[j]
        if b == K:
            seg = y[a:]
        else:
            # one step more, measurement-free: its posterior is the prior of step b,
            # the next window's start
            seg = y[a : b + 1].copy()
            seg[-1] = np.nan
        return _window_filter(ukf, a).run(x, P, seg, store="smoother", store_dtype=dtype,
                                          readout=readout)

    return run_window


def _forward_pass(
    spans: tuple[tuple[int, int], ...], run_window: Callable[[int, Array, Array], FilterResult],
    x0: Array, P0: Array, ckpt: Path, trace: _Trace,
) -> tuple[FilterResult | None, int]:
    """The first forward pass, window by window: each window's prior checkpointed in
    ``ckpt`` (when there are several), its per-step facts into ``trace``; the last
    window's run (whose gains the backward pass starts from) and the most bytes of gains
    held at once. Earlier windows' gains are dropped as soon as their facts are taken."""
    K = spans[-1][1]
    peak = 0
    x, P = x0, P0
    last: FilterResult | None = None
    for j, (a, b) in enumerate(spans):
        if len(spans) > 1 and b < K:
            np.save(ckpt / f"x{j}.npy", x)
            np.save(ckpt / f"P{j}.npy", P)
        res = run_window(j, x, P)
        peak = max(peak, _gain_bytes(res))
        trace.take(res, a, b)
        if b == K:
            last = res
        else:
            x, P = res.x_filt[-1].copy(), res.P_last.copy()
        del res
    return last, peak


def urts_smooth_windowed(
    ukf: UnscentedKalmanFilter,
    x0: Array,
    P0: Array,
    y: Array,
    *,
    readout: Array | None = None,
    smooth_readout: Array | None = None,
    max_store_bytes: int | None = None,
    window: int | None = None,
    workers: int = 1,
    store_dtype: type[np.floating] | None = None,
    backend: Backend = "auto",
) -> WindowedSmootherResult:
    """Forward filter and unscented RTS smoother in bounded memory (module docstring).

    Parameters
    ----------
    ukf : UnscentedKalmanFilter — the filter (its model steps are the session's).
    x0, P0, y, readout, store_dtype : as :meth:`UnscentedKalmanFilter.run`.
    smooth_readout : ndarray (q, n), optional — rows the smoothed readout has after
        ``readout``'s and the forward pass's has not (their variances cost q n^2 a step).
    max_store_bytes : int, optional — bytes of gains held at one time, all workers
        together; default :data:`DEFAULT_MAX_STORE_BYTES`.
    window : int, optional — steps per window; default: the whole session if its gains
        fit ``max_store_bytes``, else as many as fit.
    workers : int — threads re-running windows while the backward pass goes on (the
        compiled kernels and BLAS release the GIL).
    backend : {"auto", "numba", "numpy"} — of the backward pass.

    Returns
    -------
    WindowedSmootherResult — equal to ``urts_smooth(ukf.run(..., store="smoother"))``
    to rounding, whatever the windows.
    """
    if workers < 1:
        raise ConfigError(f"workers must be at least 1, got {workers}")
    if max_store_bytes is None:
        max_store_bytes = DEFAULT_MAX_STORE_BYTES
    x0, P0, y = check_prior(x0, P0, y)
    K, m = y.shape
    n = x0.shape[0]
    dtype = gain_dtype(n, store_dtype)
    held = 1 if workers == 1 else workers + 1  # windows being re-run + the one smoothed
    if window is None:
        window = window_steps(K, n, itemsize=dtype.itemsize, max_store_bytes=max_store_bytes,
                              held=held)
    if window < 1:
        raise ConfigError(f"window must be at least 1 step, got {window}")
    spans = tuple((a, min(a + window, K)) for a in range(0, K, window))
    M = readout_matrix(readout, n)
    p = M.shape[0]
    ro_arg = None if readout is None else M
    back = ro_arg if smooth_readout is None else np.vstack(
        [M, readout_matrix(smooth_readout, n)])
    run_window = _window_runner(ukf, y, spans, dtype, ro_arg)
    trace = _Trace(K, m, p)

    t0 = time.perf_counter()
    _remove_stale_checkpoints()
    with tempfile.TemporaryDirectory(prefix=f"{CHECKPOINT_PREFIX}{os.getpid()}-") as tmp:
        ckpt = Path(tmp)
        last, peak = _forward_pass(spans, run_window, x0, P0, ckpt, trace)
        t1 = time.perf_counter()

        def rerun(j: int) -> FilterResult:
            return run_window(j, np.load(ckpt / f"x{j}.npy"), np.load(ckpt / f"P{j}.npy"))

        held_last = [last]
        del last  # the list is the only reference: the pass frees it once smoothed
        smoothed, peak_back = _backward_pass(spans, held_last, rerun, workers, held, back,
                                             backend, n)
        peak = max(peak, peak_back)

    t2 = time.perf_counter()
    return WindowedSmootherResult(forward=trace.result(), smoothed=smoothed, windows=spans,
                                  peak_store_bytes=peak, forward_s=t1 - t0, backward_s=t2 - t1)


CHECKPOINT_PREFIX = "brakethermo-urts-"


def _remove_stale_checkpoints() -> None:
    """Delete checkpoint folders left by runs that were killed (their process is gone)."""
    for folder in Path(tempfile.gettempdir()).glob(f"{CHECKPOINT_PREFIX}*-*"):
        pid = folder.name[len(CHECKPOINT_PREFIX):].split("-", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            shutil.rmtree(folder, ignore_errors=True)
        except PermissionError:  # another user's live process
            continue


def _gain_bytes(res: FilterResult) -> int:
    return 0 if res.G is None else res.G.nbytes + res.Sigma.nbytes


def _backwards(
    J: int,
    last: list[FilterResult],
    rerun: Callable[[int], FilterResult],
    pool: ThreadPoolExecutor | None,
    workers: int,
) -> Iterator[tuple[int, FilterResult]]:
    """Windows J-1 .. 0 with their gains: the last from the first pass, the others re-run.

    With a pool, up to ``workers`` re-runs go on ahead of the window being smoothed.
    """
    yield J - 1, last.pop()
    if pool is None:
        for j in range(J - 2, -1, -1):
            yield j, rerun(j)
        return
    pending: dict[int, Future[FilterResult]] = {}
    ahead = J - 2
    for j in range(J - 2, -1, -1):
        while ahead >= 0 and ahead >= j - workers + 1:
            pending[ahead] = pool.submit(rerun, ahead)
            ahead -= 1
        yield j, pending.pop(j).result()
