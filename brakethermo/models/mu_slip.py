"""μ–slip curve estimators: Rudd's EKF on [μp, sp], batch Levenberg–Marquardt, curve families.

The EKF (Rudd 2011) treats the two parameters of μ(s) = 2 μp sp s / (sp² + s²) as a
constant state observed through the curve one point at a time, in slip order as the
ramp logs them. Its measurement noise is the logged noise inflated by a constant factor
plus the pseudo-noise of the second-order terms of the linearisation, evaluated with
the prior covariance (paper: squares of ½ h_ii P_ii and of h_ij √(P_ii P_jj), the
correlation taken as 1 so a negative one cannot shrink the noise). It starts at the
high end of the expected range with a covariance covering the range, and runs once.

Beyond the paper, :func:`fit_families` fits the two-parameter curve, Burckhardt's
three parameters and the Magic Formula's B, C, D by least squares, scores each by
cross-validated (held-out) RMSE, and reports the peak of the best one. A smoothing spline
(:func:`fit_spline`) competes with them on the same folds: a tyre whose peak is sharper
than every family's (a brush tyre: the bristles saturate while the sliding friction
falls) is fitted late by each of them — the Magic Formula's peak 0.02-0.03 in slip after
the truth on our brush simulator — and the spline, which assumes no shape, then wins
held-out and puts the peak where the points have it. On a curve of a family's own shape,
or on a few noisy points (the paper's 40), the family wins and is reported. On a braking ramp
the force lags the slip (the tyre's relaxation length, the force sensors' response), so
the measured (slip, μ) points trace the curve late, most where the slip runs away past
the peak: :func:`choose_relaxation` aligns the slip with the force over the length the
held-out points choose.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_smoothing_spline
from scipy.optimize import least_squares

from brakethermo.estimation.ekf import ExtendedKalmanFilter
from brakethermo.estimation.results import FilterResult
from brakethermo.numeric import rmse
from brakethermo.rigs.tyre import (
    burckhardt_mu,
    burckhardt_peak,
    magic_formula_mu,
    magic_formula_peak,
    relaxation_lag,
    rudd_hessian,
    rudd_jacobian,
    rudd_mu,
)

Array = NDArray[np.float64]


def rudd_ekf(
    s: Array,
    mu: Array,
    sigma: float,
    x0: Array,
    P0: Array,
    *,
    inflation: float = 3.0,
) -> FilterResult:
    """One pass of Rudd's EKF over the points (s_i, μ_i).

    Parameters
    ----------
    s, mu : ndarray (K,) — slip, –, and friction coefficient, –, in logged order.
    sigma : float — measurement noise std of μ, –.
    x0 : ndarray (2,) — initial [μp, sp].
    P0 : ndarray (2, 2) — initial covariance.
    inflation : float — constant factor on the noise std (paper: 3).

    Returns
    -------
    FilterResult
        ``x_filt[k]`` = [μp, sp] after point k, ``P_filt`` the covariances (store "full").
    """
    s = np.asarray(s, float)

    def f(X: Array, k: int) -> Array:
        return X  # constant parameters

    def h(X: Array, k: int) -> Array:
        return rudd_mu(s[k], X[:, 0], X[:, 1])[:, None]

    def pseudo(x: Array, P: Array, k: int) -> Array:
        h_mm, h_ss, h_ms = rudd_hessian(float(s[k]), float(x[0]), float(x[1]))
        p_m, p_s = max(P[0, 0], 0.0), max(P[1, 1], 0.0)
        var = (0.5 * h_mm * p_m) ** 2 + (0.5 * h_ss * p_s) ** 2 + (h_ms * np.sqrt(p_m * p_s)) ** 2
        return np.array([[var]])

    ekf = ExtendedKalmanFilter(
        f,
        np.zeros((2, 2)),
        np.array([[(inflation * sigma) ** 2]]),
        h=h,
        pseudo_noise=pseudo,
        F_jac=lambda x, k: np.eye(2),
    )
    return ekf.run(
        np.asarray(x0, float), np.asarray(P0, float), np.asarray(mu, float)[:, None], store="full"
    )


def rudd_lm(s: Array, mu: Array, x0: Array, iterations: int | None) -> tuple[Array, Array]:
    """Levenberg–Marquardt fit of Rudd's curve: ``iterations`` Jacobian evaluations, or converged.

    Returns
    -------
    x : ndarray (2,) — [μp, sp].
    std : ndarray (2,) — standard errors from the final Jacobian and residual variance.
    """
    s, mu = np.asarray(s, float), np.asarray(mu, float)

    def res(p: Array) -> Array:
        return rudd_mu(s, p[0], p[1]) - mu

    def jac(p: Array) -> Array:
        return rudd_jacobian(s, p[0], p[1])

    x = np.asarray(x0, float).copy()
    if iterations is None:
        x = least_squares(res, x, jac=jac, method="lm").x
    else:
        lam = 1e-3
        for _ in range(iterations):  # Marquardt steps, one Jacobian (one pass) each
            r, J = res(x), jac(x)
            A, g = J.T @ J, J.T @ r
            while True:
                step = np.linalg.solve(A + lam * np.diag(np.diag(A)), -g)
                if np.sum(res(x + step) ** 2) < np.sum(r * r) or lam > 1e8:
                    x = x + step
                    lam *= 0.1
                    break
                lam *= 10.0
    J, r = jac(x), res(x)
    dof = max(s.size - 2, 1)
    cov = np.linalg.pinv(J.T @ J) * float(r @ r) / dof
    return x, np.sqrt(np.diag(cov))


@dataclass(frozen=True)
class Family:
    """A μ(s) curve family: ``curve(s, *p)``, ``peak(*p) -> (μ, s)``, start and bounds."""

    name: str
    params: tuple[str, ...]
    curve: Callable[..., Array]
    peak: Callable[..., tuple[float, float]]
    start: Callable[[float, float], Array]  # from a rough (μ peak, slip peak)
    lower: tuple[float, ...]
    upper: tuple[float, ...]


def _rudd_peak(mu_p: float, s_p: float) -> tuple[float, float]:
    return float(mu_p), float(s_p)


FAMILIES: tuple[Family, ...] = (
    Family(
        "rudd",
        ("mu_p", "s_p"),
        rudd_mu,
        _rudd_peak,
        lambda m, sp: np.array([m, sp]),
        (0.0, 1e-3),
        (5.0, 1.0),
    ),
    Family(
        "burckhardt",
        ("c1", "c2", "c3"),
        burckhardt_mu,
        burckhardt_peak,
        lambda m, sp: np.array([1.1 * m, 3.0 / sp, 0.3 * m]),
        (0.0, 0.1, 0.0),
        (5.0, 500.0, 5.0),
    ),
    Family(
        "magic-formula",
        ("B", "C", "D"),
        magic_formula_mu,
        magic_formula_peak,
        lambda m, sp: np.array([np.tan(np.pi / 3.2) / sp, 1.6, m]),
        (0.1, 1.0, 0.0),
        (500.0, 2.0, 5.0),
    ),
)


@dataclass(frozen=True)
class FamilyFit:
    """One family fitted to all points, with its cross-validated error and peak.

    ``curve`` is μ(s) of a fit that is no :data:`FAMILIES` member (the smoothing spline:
    its ``params`` describe it, they do not define it); None for a family's.
    ``heldout_err`` is each point's held-out error (fit minus point, –), in the points'
    order.
    """

    name: str
    params: dict[str, float]
    rmse: float
    heldout_rmse: float
    mu_peak: float
    slip_peak: float
    curve: Callable[[Array], Array] | None = field(default=None, compare=False, repr=False)
    heldout_err: Array | None = field(default=None, compare=False, repr=False)

    def __call__(self, s: Array) -> Array:
        """μ at the slips ``s`` (–)."""
        if self.curve is not None:
            return self.curve(s)
        return FAMILY[self.name].curve(s, *self.params.values())


def _fit(fam: Family, s: Array, mu: Array, p0: Array) -> Array:
    p0 = np.clip(p0, np.array(fam.lower) + 1e-9, np.array(fam.upper) - 1e-9)
    return least_squares(
        lambda p: fam.curve(s, *p) - mu, p0, bounds=(fam.lower, fam.upper), method="trf"
    ).x


FAMILY = {f.name: f for f in FAMILIES}


def fit_families(s: Array, mu: Array, *, folds: int = 5, seed: int = 0,
                 blocks: int | None = None, spline: bool = False) -> list[FamilyFit]:
    """Fit every family of :data:`FAMILIES`; held-out RMSE by ``folds``-fold cross-validation.

    Parameters
    ----------
    s, mu : ndarray (K,) — slip, –, and friction coefficient, –.
    folds : int — cross-validation folds (random, fixed ``seed``).
    blocks : int, optional — instead, cut the points (in time order) into this many runs
        of neighbours, dealt to the folds in turn.
    spline : bool — the smoothing spline (:func:`fit_spline`) competes too, on the same
        folds, where it finds a peak inside the points. Not where the slip's alignment is
        chosen: a curve of any shape follows a lagged slip as well as the aligned one.
    """
    s, mu = np.asarray(s, float), np.asarray(mu, float)
    i = int(np.argmax(np.convolve(mu, np.ones(25) / 25, mode="same")))
    m0, sp0 = float(mu[max(i - 12, 0) : i + 13].mean()), max(float(s[i]), 0.02)
    fold = (np.random.default_rng(seed).permutation(s.size) if blocks is None
            else np.arange(s.size) * blocks // max(s.size, 1)) % folds
    out = []
    for fam in FAMILIES:
        p = _fit(fam, s, mu, fam.start(m0, sp0))
        err = np.empty(s.size)
        for j in range(folds):
            tr, te = fold != j, fold == j
            err[te] = fam.curve(s[te], *_fit(fam, s[tr], mu[tr], p)) - mu[te]
        mu_pk, s_pk = fam.peak(*(float(v) for v in p))
        out.append(
            FamilyFit(
                fam.name,
                dict(zip(fam.params, (float(v) for v in p), strict=True)),
                rmse(fam.curve(s, *p), mu),
                rmse(err),
                mu_pk,
                s_pk,
                heldout_err=err,
            )
        )
    if spline and (curve := fit_spline(s, mu, fold)) is not None:
        out.append(curve)
    return out


SPLINE = "smoothing-spline"
SPLINE_BIN = 0.002  # slip: points closer than this are one abscissa of the spline (mean μ)
SPLINE_MIN_BINS = 20  # fewer distinct slips: no curve of its own shape worth fitting
PEAK_GRID = 4000  # slips between the smallest and largest point where the maximum is sought


def _spline(s: Array, mu: Array) -> tuple[Callable[[Array], Array], float, float, int]:
    """A cubic smoothing spline of μ(s), its smoothing chosen by generalised
    cross-validation (:func:`scipy.interpolate.make_smoothing_spline`), on the points
    binned by :data:`SPLINE_BIN` in slip (mean slip and μ per bin, weighted by its count:
    the ramp logs many points at nearly one slip, which the criterion cannot tell
    apart). Held at its end values outside the points' slips. Returns μ(s), the smallest
    and largest binned slip and the number of bins."""
    k = np.round(s / SPLINE_BIN).astype(np.int64)
    _, inv = np.unique(k, return_inverse=True)
    n = np.bincount(inv).astype(float)
    x, y = np.bincount(inv, s) / n, np.bincount(inv, mu) / n
    if x.size < SPLINE_MIN_BINS:
        raise ValueError("too few distinct slips")
    spl = make_smoothing_spline(x, y, w=n)
    lo, hi = float(x[0]), float(x[-1])
    return (lambda v: spl(np.clip(v, lo, hi))), lo, hi, x.size


def fit_spline(s: Array, mu: Array, fold: NDArray[np.int_]) -> FamilyFit | None:
    """The smoothing spline as one more candidate curve (:func:`_spline`), scored on the
    folds ``fold`` (one label per point) as the families are; None where it cannot be
    fitted (too few distinct slips) or has no maximum inside the points (still rising at
    the largest slip: no peak to give)."""
    try:
        curve, lo, hi, bins = _spline(s, mu)
        err = np.empty(s.size)
        for j in np.unique(fold):
            tr, te = fold != j, fold == j
            err[te] = _spline(s[tr], mu[tr])[0](s[te]) - mu[te]
    except ValueError:  # too few slips, or a criterion scipy finds ill-posed
        return None
    g = np.linspace(lo, hi, PEAK_GRID)
    v = curve(g)
    i = int(np.argmax(v))
    if i in (0, g.size - 1):
        return None
    return FamilyFit(SPLINE, {"bins": float(bins), "bin_width": SPLINE_BIN},
                     rmse(curve(s), mu), rmse(err), float(v[i]), float(g[i]), curve=curve,
                     heldout_err=err)


# Relaxation lengths tried, m: none, a racing slick's few centimetres, a road tyre's
# 0.2-0.5 m, and what a lagging load cell adds at speed
RELAXATION_M = (0.0, 0.03, 0.05, 0.08, 0.12, 0.18, 0.25, 0.35, 0.5, 0.7, 1.0, 1.4)
SIMPLER_WITHIN = 0.02  # a shorter length within this fraction of the best held-out RMSE wins


@dataclass(frozen=True)
class RelaxationChoice:
    """The relaxation length a ramp's held-out points choose.

    Attributes
    ----------
    length_m : float — m, the chosen σ (0: the slip as logged).
    candidates_m : tuple of float — the lengths tried, m.
    heldout_rmse : tuple of float — the best family's held-out RMSE of μ at each, –.
    as_logged : list of FamilyFit — the families fitted to the slip as logged (σ = 0):
        the alignment is a model too, and the peak's band admits what they say.
    """

    length_m: float
    candidates_m: tuple[float, ...]
    heldout_rmse: tuple[float, ...]
    as_logged: list[FamilyFit]


HELD_BLOCKS = 25  # runs of neighbouring points held out together when σ is chosen


def choose_relaxation(t: Array, s: Array, mu: Array, speed: Array,
                      kept: Array | None = None) -> tuple[RelaxationChoice, Array]:
    """The slip aligned with the force, and the length that aligns it.

    Each candidate σ lags the logged slip by σ / V (:func:`relaxation_lag`: the force
    follows the slip it had σ of travel earlier); the families are fitted to the lagged
    slip and scored on held-out runs of neighbouring points (:func:`fit_families` with
    ``blocks``: a point beside its fitted neighbours 1 ms away is no held-out point); the
    shortest σ within :data:`SIMPLER_WITHIN` of the best score wins, so a ramp whose force
    keeps up with its slip keeps the slip as logged.

    Parameters
    ----------
    t : ndarray (K,) — s, the whole ramp in time order.
    s : ndarray (K,) — slip over the whole ramp, –.
    mu : ndarray — friction coefficient at the points ``kept``, –.
    speed : ndarray (K,) — carriage speed, m/s.
    kept : ndarray of int, optional — the points of the ramp that have a μ (default all).
    """
    idx = np.arange(s.size) if kept is None else np.asarray(kept)
    fits = [fit_families(relaxation_lag(s, t, speed, L)[idx], mu, blocks=HELD_BLOCKS)
            for L in RELAXATION_M]
    scores = [min(f.heldout_rmse for f in fam) for fam in fits]
    best = min(scores)
    i = next(i for i, v in enumerate(scores) if v <= best * (1.0 + SIMPLER_WITHIN))
    choice = RelaxationChoice(RELAXATION_M[i], RELAXATION_M, tuple(scores), fits[0])
    return choice, relaxation_lag(s, t, speed, choice.length_m)[idx]


# The spline is the answer where it beats the best family held-out by at least this many
# standard errors of the difference (mean squared error per run of neighbouring points,
# HELD_BLOCKS runs): a curve of no shape fits a few noisy points' wobble and can win
# their folds by chance (the paper's 40 points, 40 seeds: 6 won by least held-out RMSE,
# their peak slips up to 0.061 off, where the family's were within 0.011; 1 won with this
# margin), while a family's wrong shape costs it at every ramp point near the peak (our
# brush tyres, dry and wet: 1.5-2.5 standard errors)
SPLINE_CLEARLY = 1.0


def best_fit(fits: list[FamilyFit]) -> FamilyFit:
    """The curve whose peak is reported: the family of least held-out RMSE, or the
    smoothing spline where it beats that family clearly (:data:`SPLINE_CLEARLY`)."""
    best = min((f for f in fits if f.curve is None), key=lambda f: f.heldout_rmse)
    spline = next((f for f in fits if f.name == SPLINE), None)
    if spline is None or spline.heldout_err is None or best.heldout_err is None:
        return best
    gain = best.heldout_err**2 - spline.heldout_err**2
    runs = np.array([r.mean() for r in np.array_split(gain, min(HELD_BLOCKS, gain.size))])
    se = float(np.std(runs, ddof=1)) / np.sqrt(runs.size)
    return spline if runs.mean() > SPLINE_CLEARLY * se else best
