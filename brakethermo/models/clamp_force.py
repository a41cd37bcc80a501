"""State-space models of the clamp-force estimator (Saric & Bab-Hadiashar 2007, §3).

The paper's scalar Kalman filter: the dynamic stiffness model (eq. 6) is the process,
F(k) = α0 F(k−1) + B u(k) with B u(k) the cubic in the motor angle (eq. 12), and the
torque balance (eq. 7) is the measurement, z(k) = F(k) + v (H = 1, eq. 13); Q and R are
the squared training RMSEs of the two models (constant), P(0) = Q.

Beyond the paper, the adaptive variant adds a random-walk stiffness factor s,
F(k) = α0 F(k−1) + s(k) u(k), s(k) = s(k−1) + w: a two-state filter linear in the state
for a known input, whose transition [[α0, u(k)], [0, 1]] varies with the motor angle.
Pads that soften as they heat (or stiffen with wear) pull s away from 1, and the torque
balance, which does not depend on the pads, tells the filter by how much.

The filter the tool reports (``kf``) is decided by the session itself: the paper's
fixed filter where its mean NIS stays under :data:`NIS_LIMIT` (its innovations as large
as its noise settings admit: the pads are the trained ones), else the adaptive filter —
the stiffness model no longer holds (heat, wear), and the filter that learns the pads'
stiffness factor from the torque balance beats both a fixed filter and a noise-matched
one there (worn pads without re-training 0.60 vs 0.97 kN, heating 0.24 vs 0.45 kN, the
torque balance alone 0.93 / 0.42 kN; ``benchmarks/bench_rigs_accuracy.py``).

The training session chooses what the paper fixes (:func:`fusion_check`: trained on one
half, estimated on the other, both ways): Q is the paper's times the factor with the
smallest held-out error (the paper's unless another is clearly better: a stiffness model
whose errors are not white — hysteresis, relaxation — wants less weight); where even
that filter did worse than an input or the ML fusion there, ``kf`` is the better one
with its held-out RMSE as the band. The fixed filter stays as ``kf_paper``.

Those errors last tens of milliseconds, and the paper's filter cannot use that: with a
static stiffness model it is the ML fusion. The coloured-error smoother
(:class:`ColouredError`, :mod:`brakethermo.estimation.coloured`) carries the stiffness
model's error as a first-order Gauss–Markov state observed through the torque balance,
its correlation time and gain chosen on the same held-out halves; where it did clearly
better there, it is ``kf`` on sessions whose pads are the trained ones (nominal, five
unseen seeds: 0.202 against the paper's 0.269 kN and the ML fusion's 0.279; viscoelastic
pads 0.221 against 0.405).

The training sensor is not taken as the truth: a load cell behind an amplifier filter
reads the force late, and models fitted to it learn the lag (the paper's filter, trained
on a 5 ms sensor, 0.59 kN from the true force with a 95 % band covering it 69 % of the
time). The motor current answers the load at once: :func:`lag_scores` scores each
candidate lag by how well its de-lagged sensor (F + τ dF/dt) lets eq. 7 predict the
current on held-out blocks (the pipeline adopts one only where the data clearly show
it); the models are fitted to, and the held-out check scores against, the sensor with
that lag taken out (the same 5 ms caliper: 0.28 kN, coverage 94 %).

The reported filter's band admits what its innovations show: where its mean NIS lies
above the χ² band (over-confident: the pads moved further than its noise allows), its Q
and R are scaled alike by that mean NIS — the gain, and so the estimate, unchanged, the
covariance scaled by the factor (covariance matching of the noise level, Mehra 1972);
the held-out likelihood of the training session's sensor sets the least factor.
Worn pads without re-training, development seeds: 95 % coverage 67–73 % → 88–91 %.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from brakethermo.errors import ConfigError
from brakethermo.estimation.coloured import (
    error_filter,
    error_smoother,
    smoothed_variance,
)
from brakethermo.estimation.consistency import nis_consistency, variance_scale
from brakethermo.estimation.kf import LinearFilterResult, kalman_filter_tv
from brakethermo.numeric import rmse
from brakethermo.rigs.emb import (
    DynamicStiffness,
    TorqueBalance,
    fit_dynamic_stiffness,
    fit_torque_balance,
    friction_sign,
    ml_fusion,
    motor_rates,
    sensor_delagged,
    torque_balance_force,
)
from brakethermo.rigs.signals import smoothed_rate

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ClampForceModels:
    """The two trained models and their training RMSEs (σ of paper §3).

    Attributes
    ----------
    stiffness : DynamicStiffness — eq. 6.
    torque : TorqueBalance — eq. 7.
    sigma_ds : float — training RMSE of eq. 6, open loop, N (√Q).
    sigma_tb : float — training RMSE of eq. 7, N (√R).
    ts : float — sample time the models were fitted at, s.
    window : int — derivative window of the motor rates in eq. 7 (1 = the paper's
        backward differences), cross-validated (:func:`eq7_choice`).
    sensor_lag_s : float — s, time constant of the training session's clamp-force sensor
        taken out (F + τ dF/dt) before both models were fitted (0: the paper's ideal
        sensor; :func:`lag_scores`).
    """

    stiffness: DynamicStiffness
    torque: TorqueBalance
    sigma_ds: float
    sigma_tb: float
    ts: float
    window: int = 1
    sensor_lag_s: float = 0.0


# Candidate derivative windows for eq. 7, samples (1 = the paper's differences), and
# friction sign bands, rad/s (0 = the paper's sgn).
WINDOWS = (1, 5, 7, 9, 11, 15, 21)
SIGN_BANDS = (0.0, 0.05, 0.1, 0.2, 0.5, 1.0)
CV_BLOCK_S = 2.0  # s, blocks of the two-fold cross-validation of eq. 7's choices
MIN_HALF_S = 5.0  # s, shortest half of a training session the fusion is checked on
# Candidate time constants of the clamp-force sensor, s: a load cell behind an amplifier
# filter reads the force late (0 = the paper's ideal sensor, the first candidate).
SENSOR_LAGS_S = (0.0, 0.5e-3, 1e-3, 2e-3, 3e-3, 5e-3, 8e-3, 12e-3, 20e-3, 35e-3, 60e-3, 100e-3,
                 150e-3)


def _blocks(K: int, ts: float) -> NDArray[np.int_]:
    """Block of :data:`CV_BLOCK_S` seconds of each sample (its fold: the parity)."""
    return (np.arange(K) * ts // CV_BLOCK_S).astype(int)


def lag_scores(theta: Array, current: Array, F: Array, ts: float, window: int,
               band: float) -> dict[float, Array]:
    """Held-out squared error of the motor current per block (A²) for each candidate lag
    of the clamp-force sensor (:data:`SENSOR_LAGS_S`, s).

    The motor current answers the load at once (eq. 7); a sensor that lags reads the
    force late, and every model fitted to it learns the lag (on a 5 ms sensor the filter's
    95 % band covered the true force 69 % of the time). Each candidate τ de-lags the
    sensor (:func:`~brakethermo.rigs.emb.sensor_delagged`); eq. 7 plus a viscous term
    (B ω: de-lagging adds γ τ dF/dt = γ τ (dF/dθ) ω, which would otherwise stand in for an
    unmodelled speed-proportional friction) is fitted on alternate blocks of
    :data:`CV_BLOCK_S` and scored on the others, both ways. The target, the current, is
    the same for every candidate, so their errors compare (the choice and its test:
    :func:`brakethermo.pipelines.clamp_force.choose_sensor_lag`).

    Parameters
    ----------
    theta, current, F, ts : as :func:`train`.
    window : int — derivative window of the motor rates (:func:`motor_rates`).
    band : float — rad/s, friction sign band (:func:`friction_sign`).

    Returns
    -------
    dict — candidate lag (s) -> ndarray (blocks,) of held-out squared current errors, A².
    """
    block = _blocks(theta.size, ts)
    fold = block % 2
    omega, acc = motor_rates(theta, ts, window)
    sgn = friction_sign(omega, band)
    out: dict[float, Array] = {}
    for lag in SENSOR_LAGS_S:
        F_d = sensor_delagged(F, lag, ts)
        X = np.stack([F_d, acc, F_d * sgn, sgn, np.ones_like(F_d), omega], axis=1)
        ok = np.isfinite(X).all(axis=1) & np.isfinite(current)
        err = np.zeros(theta.size)
        for j in (0, 1):
            fit, test = ok & (fold == j), ok & (fold != j)
            if not fit.any() or not test.any():
                continue
            scale = np.maximum(np.abs(X[fit]).max(axis=0), 1e-300)
            coef = np.linalg.lstsq(X[fit] / scale, current[fit], rcond=None)[0] / scale
            err[test] = X[test] @ coef - current[test]
        out[lag] = np.bincount(block, weights=err**2)
    return out


def train(
    theta: Array,
    current: Array,
    F: Array,
    ts: float,
    *,
    structure: ClampForceModels | None = None,
    sensor_lag_s: float | None = None,
    eq7: tuple[int, float] | None = None,
) -> ClampForceModels:
    """Fit eq. 6 and eq. 7 by least squares on a session with the clamp-force sensor.

    Parameters
    ----------
    theta : ndarray (K,) — motor angle, rad.
    current : ndarray (K,) — motor current, A.
    F : ndarray (K,) — clamp-force sensor, N.
    ts : float — sample time, s.
    structure : ClampForceModels, optional — re-training (wear): keep its derivative
        window, friction sign band and sensor lag, which belong to the drive, the log and
        the rig rather than to the pads, and refit the parameters only. A short
        re-training session chooses them less reliably than the full training one.
    sensor_lag_s : float, optional — s, the sensor's lag, taken out (F + τ dF/dt) before
        both models are fitted (the pipeline chooses it: :func:`lag_scores`); default the
        structure's, else 0 (the paper's ideal sensor).
    eq7 : (int, float), optional — the derivative window and friction sign band when
        :func:`eq7_choice` already chose them on this (de-lagged) sensor.

    The derivative window and the friction sign band of eq. 7 are those of
    :func:`eq7_choice` on the de-lagged sensor (or the structure's).
    """
    if sensor_lag_s is None:
        sensor_lag_s = 0.0 if structure is None else structure.sensor_lag_s
    F = sensor_delagged(F, sensor_lag_s, ts)
    if structure is not None:
        window, band = structure.window, structure.torque.omega_s
    else:
        window, band = eq7 or eq7_choice(theta, current, F, ts)
    ds = fit_dynamic_stiffness(theta, F, ts)
    sigma_ds = rmse(ds.simulate(theta), F)
    rates = motor_rates(theta, ts, window)
    tb = fit_torque_balance(current, theta, ts, F, window, band, rates=rates)
    sigma_tb = rmse(torque_balance_force(current, theta, ts, tb, window, rates=rates), F)
    return ClampForceModels(ds, tb, sigma_ds, sigma_tb, ts, window, sensor_lag_s)


def eq7_choice(theta: Array, current: Array, F: Array, ts: float) -> tuple[int, float]:
    """Derivative window and friction sign band of eq. 7 (samples, rad/s).

    The pair of :data:`WINDOWS` x :data:`SIGN_BANDS` with the smallest cross-validated
    force error: fitted on alternate blocks of :data:`CV_BLOCK_S` seconds and scored on
    the others, both ways (the in-sample RMSE of a 20 s re-training session picks noise);
    the first such pair, the paper's differences and sgn first.
    """
    fold = _blocks(theta.size, ts) % 2
    omega_acc = {w: motor_rates(theta, ts, w) for w in WINDOWS}

    def cv_score(window: int, band: float) -> float:
        err = []
        for j in (0, 1):
            tb = fit_torque_balance(
                current, theta, ts, F, window, band, rows=fold == j, rates=omega_acc[window]
            )
            F_tb = torque_balance_force(current, theta, ts, tb, window, rates=omega_acc[window])
            err.append((F_tb - F)[fold != j])
        return rmse(np.concatenate(err))

    return min(((w, b) for w in WINDOWS for b in SIGN_BANDS), key=lambda wb: cv_score(*wb))


NIS_LIMIT = 1.5  # mean NIS of the fixed filter above which its model no longer holds
# How far the motor side alone moves the torque balance against the stiffness model: a PM
# motor's torque constant falls about 0.1 %/K of magnet temperature, a gear's efficiency
# moves a few per cent with its grease; a stiffness factor within this of 1 could be either
MOTOR_SPAN = 0.2
SCALE_SEEN = 0.03  # a stiffness factor nearer 1 than this is no scale change to speak of


# Factors on the paper's Q (the stiffness model's training RMSE squared) the held-out
# check tries; the filter's estimate depends on Q/R only, so this spans its gain.
Q_SCALES = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0)
Q_MARGIN = 0.05  # another factor replaces the paper's only when 5 % better held out
SINGLES = ("stiffness", "torque_balance", "ml_fusion")
# Correlation times (s) and steady-state gains of the coloured-error smoother the held-out
# check tries (τ = 0: a white stiffness error, where g = Q/(Q+R) is the ML fusion).
COLOURED_TAUS_S = (0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)
COLOURED_GAINS = tuple(float(g) for g in 10.0 ** np.arange(-4.0, -0.24, 0.25))


def _phi(tau_s: float, ts: float) -> float:
    """A first-order error's one-step correlation e^(−ts/τ) (0 for a white error), –."""
    return float(np.exp(-ts / tau_s)) if tau_s > 0.0 else 0.0


@dataclass(frozen=True)
class ColouredError:
    """The coloured-error smoother the training session's held-out halves chose.

    The stiffness model's error as a first-order Gauss–Markov state observed through the
    torque balance (:mod:`brakethermo.estimation.coloured`): its hysteresis and relaxation
    last tens of milliseconds, which the paper's filter, taking it as white, cannot use.

    Attributes
    ----------
    tau_s : float — s, the error's correlation time (0: white).
    gain : float — the steady-state Kalman gain, –.
    rmse_n : float — N, held-out RMSE of the smoothed estimate (both halves pooled).
    innovation_var : float — N², held-out mean squared innovation (the filter's S).
    band_scale : float — factor on the model's smoothed variance that maximises the
        held-out Gaussian likelihood of the sensor's force, at least 1.
    adopted : bool — it did :data:`Q_MARGIN` better held out than the filter the check
        chose otherwise: it is the reported estimate where the pads are the trained ones.
    holds : bool — it did at least as well there as the best of its inputs and the ML
        fusion (else that is reported in its place, as for the filter).
    rate_knots, rate_vars : tuple of float — N/s and N²: the held-out mean squared error
        of the estimate in bins of its own force rate (equal counts, each bin's median
        rate, made non-decreasing); the band's variance is at least that, interpolated at
        the session's rate. The stiffness model's hysteresis and relaxation err most
        where the force moves fast: on an independent caliper a constant band covered
        60 % of the samples where the force changed fastest and all of the still ones.
    force_knots, force_vars : tuple of float — N and N²: the same in bins of the estimated
        force; the band's variance is at least that too. A progressive stiffness the
        model follows less well at high force errs at steady holds, where the rate says
        nothing: another independent caliper's validation session, banded by rate alone,
        covered 44 % of its holds above 20 kN (0.74 kN RMS, +0.43 kN biased) and 81.5 % of
        its applied samples; 99.6 % with this term.
    """

    tau_s: float
    gain: float
    rmse_n: float
    innovation_var: float
    band_scale: float
    adopted: bool
    holds: bool
    rate_knots: tuple[float, ...] = ()
    rate_vars: tuple[float, ...] = ()
    force_knots: tuple[float, ...] = ()
    force_vars: tuple[float, ...] = ()

    def phi(self, ts: float) -> float:
        """The one-step correlation e^(−ts/τ), –."""
        return _phi(self.tau_s, ts)

    def variance(self, ts: float, rate: Array | float = 0.0, force: Array | float = 0.0
                 ) -> Array | float:
        """N², the smoothed estimate's variance where its force is ``force`` (N) and moves
        at ``rate`` (N/s), times the held-out factor on it."""
        r = self.innovation_var * (1.0 - self.gain)
        steady = smoothed_variance(self.phi(ts), self.gain, r)
        out = np.maximum(steady, np.interp(np.abs(rate), self.rate_knots, self.rate_vars)
                         ) if self.rate_knots else steady
        if self.force_knots:
            out = np.maximum(out, np.interp(force, self.force_knots, self.force_vars))
        return self.band_scale * out


@dataclass(frozen=True)
class FusionCheck:
    """The filter against what else could be reported, on held-out halves of the
    training session (trained on one half, estimated on the other, both ways).

    Attributes
    ----------
    rmse_n : dict — held-out RMSE (N) of ``kf`` (at ``q_scale``), ``ml_fusion``,
        ``stiffness`` and ``torque_balance``, the two halves pooled.
    best_single : str — the best of the two inputs and the ML fusion there.
    fusion_holds : bool — the filter did at least as well as ``best_single``.
    q_scale : float — the factor on the paper's Q with the smallest held-out RMSE (1, the
        paper's, unless another is :data:`Q_MARGIN` better).
    rmse_by_q : dict — held-out RMSE (N) of the filter per factor tried.
    band_scale : float — factor on the filter's variance that maximises the held-out
        Gaussian likelihood of the sensor's force, mean((kf − F)² / var), at least 1 (the
        sensor's own noise and lag count as error: conservative).
    adaptive : bool — the adaptive-stiffness filter (at ``q_scale``) did :data:`Q_MARGIN`
        better held out than the fixed one: it is reported whatever the session's NIS.
    adaptive_rmse_by_q : dict — held-out RMSE (N) of the adaptive filter per factor.
    """

    rmse_n: dict[str, float]
    best_single: str
    fusion_holds: bool
    q_scale: float = 1.0
    rmse_by_q: dict[float, float] | None = None
    band_scale: float = 1.0
    adaptive: bool = False
    adaptive_rmse_by_q: dict[float, float] | None = None
    coloured: ColouredError | None = None


def fusion_check(theta: Array, current: Array, F: Array, ts: float, *,
                 factor_walk: float = 0.02, sensor_lag_s: float = 0.0
                 ) -> FusionCheck | None:
    """Choose the filter's Q and check it against its inputs on held-out halves.

    The paper sets Q and R to the two models' training RMSEs squared; on a rig whose
    errors are not white (a lagging, drifting stiffness model) that gain can make the
    fusion worse than what it fuses. Here each factor of :data:`Q_SCALES` is scored by
    the held-out RMSE against the sensor with its lag ``sensor_lag_s`` (s, the trained
    models') taken out, which both halves' models take. ``None`` when a half is shorter
    than :data:`MIN_HALF_S` (nothing to judge on).
    """
    K = theta.size
    half = K // 2
    if half * ts < MIN_HALF_S:
        return None
    F_d = sensor_delagged(F, sensor_lag_s, ts)
    sq: dict[str | float | tuple[str, float], list[Array]] = {}
    z2: dict[float | tuple[str, float], list[Array]] = {}
    halves: list[tuple[Array, Array, Array]] = []
    for fit_rows, test_rows in ((slice(0, half), slice(half, K)),
                                (slice(half, K), slice(0, half))):
        m = train(theta[fit_rows], current[fit_rows], F[fit_rows], ts,
                  sensor_lag_s=sensor_lag_s)
        for q in Q_SCALES:
            e = estimate(m, theta[test_rows], current[test_rows], ts, factor_walk=factor_walk,
                         q_scale=q)
            for key, x, std in ((q, e.kf, e.kf_std), (("adaptive", q), e.adaptive,
                                                       e.adaptive_std)):
                sq.setdefault(key, []).append((x - F_d[test_rows]) ** 2)
                z2.setdefault(key, []).append(sq[key][-1] / std**2)
        for name, x in (("ml_fusion", e.ml_fusion), ("stiffness", e.stiffness),
                        ("torque_balance", e.torque_balance)):
            sq.setdefault(name, []).append((x - F_d[test_rows]) ** 2)
        halves.append((e.stiffness, e.torque_balance, F_d[test_rows]))
    rms = {k: float(np.sqrt(np.nanmean(np.concatenate(v)))) for k, v in sq.items()}
    by_q = {q: rms.pop(q) for q in Q_SCALES}
    adaptive_by_q = {q: rms.pop(("adaptive", q)) for q in Q_SCALES}
    q_best = min(Q_SCALES, key=by_q.__getitem__)
    q_best = q_best if by_q[q_best] < (1.0 - Q_MARGIN) * by_q[1.0] else 1.0
    adaptive = adaptive_by_q[q_best] < (1.0 - Q_MARGIN) * by_q[q_best]
    chosen: float | tuple[str, float] = ("adaptive", q_best) if adaptive else q_best
    rms = {"kf": adaptive_by_q[q_best] if adaptive else by_q[q_best],
           **{k: v for k, v in rms.items() if isinstance(k, str)}}
    best = min(SINGLES, key=rms.__getitem__)
    coloured = _coloured_choice(halves, ts, rms["kf"], rms[best])
    band = band_factor(np.concatenate(z2[chosen]))
    return FusionCheck(rms, best, rms["kf"] <= rms[best], q_best, by_q, band, adaptive,
                       adaptive_by_q, coloured)


def band_factor(z2: Array) -> float:
    """Factor on the filter's variance from its held-out squared standardised errors:
    their mean (a Gaussian's is 1), or what brings 95 % of them inside the 95 % band if
    that is more (errors with heavy tails — a lag, a hysteresis — cover too little at a
    mean of 1: 90 % on an independent caliper), never below 1."""
    z2 = z2[np.isfinite(z2)]
    if z2.size == 0:
        return 1.0
    return max(1.0, float(np.mean(z2)), float(np.quantile(z2, 0.95)) / 1.96**2)


RATE_BINS = 8  # bins of the force rate the coloured smoother's band is measured in


def _rate_bins(rate: Array, e2: Array) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Each of :data:`RATE_BINS` equal-count bins of ``rate`` (N/s): its median rate and
    the mean of ``e2`` (N²) there, made non-decreasing with the rate; empty when too
    few finite samples."""
    ok = np.isfinite(rate) & np.isfinite(e2)
    if ok.sum() < 20 * RATE_BINS:
        return (), ()
    order = np.argsort(rate[ok])
    parts = np.array_split(order, RATE_BINS)
    knots = [float(np.median(rate[ok][p])) for p in parts]
    mse = np.maximum.accumulate([float(np.mean(e2[ok][p])) for p in parts])
    return tuple(knots), tuple(float(v) for v in mse)


def _coloured_choice(halves: list[tuple[Array, Array, Array]], ts: float, rmse_kf: float,
                     rmse_best: float) -> ColouredError:
    """The (τ, g) of :data:`COLOURED_TAUS_S` x :data:`COLOURED_GAINS` with the smallest
    held-out RMSE, its innovation variance and band factor there.

    Parameters
    ----------
    halves : list of (stiffness, torque balance, de-lagged sensor) on each held-out half,
        N, from the models trained on the other half.
    ts : float — s, sample time.
    rmse_kf : float — N, the held-out RMSE of the filter chosen otherwise.
    rmse_best : float — N, the held-out RMSE of the best of its inputs and the ML fusion.
    """
    def estimates(tau: float, g: float) -> list[Array]:
        return [ds - error_smoother(ds - tb, _phi(tau, ts), g) for ds, tb, _ in halves]

    def errors(tau: float, g: float) -> Array:
        return np.concatenate([x - F for x, (_, _, F) in zip(estimates(tau, g), halves,
                                                             strict=True)])

    grid = {(tau, g): float(np.sqrt(np.nanmean(errors(tau, g) ** 2)))
            for tau in COLOURED_TAUS_S for g in COLOURED_GAINS}
    tau, g = min(grid, key=grid.__getitem__)
    choice = ColouredError(tau, g, grid[tau, g], 1.0, 1.0, False, True)
    nu = np.concatenate([error_filter(ds - tb, choice.phi(ts), g)[1] for ds, tb, _ in halves])
    S = float(np.nanmean(nu**2))
    e2 = errors(tau, g) ** 2
    est = np.concatenate(estimates(tau, g))
    rate = np.abs(np.concatenate([smoothed_rate(x, ts) for x in estimates(tau, g)]))
    knots, mse = _rate_bins(rate, e2)
    f_knots, f_mse = _rate_bins(est, e2)
    choice = replace(choice, innovation_var=S, rate_knots=knots, rate_vars=mse,
                     force_knots=f_knots, force_vars=f_mse)
    z2 = e2 / choice.variance(ts, rate, est)
    return replace(choice, band_scale=band_factor(z2),
                   adopted=grid[tau, g] < (1.0 - Q_MARGIN) * rmse_kf,
                   holds=grid[tau, g] <= rmse_best)


@dataclass(frozen=True)
class ClampForceEstimates:
    """Every estimate of one session, N (factor –).

    Attributes
    ----------
    kf, kf_std : ndarray — the reported estimate (module docstring), mean and std.
    kf_paper : ndarray — the fixed filter (eq. 9-13), its Q the held-out choice.
    kf_paper_nis : float — mean NIS of the fixed filter on this session (1 = consistent).
    ml_fusion : ndarray — eq. 8.
    stiffness : ndarray — eq. 6 open loop.
    torque_balance : ndarray — eq. 7.
    adaptive, adaptive_std : ndarray — KF with the random-walk stiffness factor (its
        filter's own std: the held-out check scores against it).
    stiffness_factor, stiffness_factor_std : ndarray — its factor s.
    kf_source : str — what ``kf`` is: ``"kf"`` (the filter), or what the training
        session's held-out check fell back to (``stiffness``, ``torque_balance`` or
        ``ml_fusion``).
    kf_noise_scale : float — factor on the reported filter's Q and R (so on its
        variance) matching its innovations, 1 where they are consistent (for the fixed
        and adaptive filters at least the held-out likelihood's factor; the coloured
        smoother carries that factor in its variance, and this is on top of it).
    kf_consistency : dict — :func:`nis_consistency` of the reported filter, before the
        scaling.
    kf_filter : str — the filter the session calls for: ``"fixed"`` (the paper's),
        ``"adaptive"`` or ``"coloured"``; ``kf`` where ``kf_source`` is ``"kf"``, else
        what the held-out check found worse than ``kf_source``.
    motor_alike : float or None — where the reported adaptive filter's median stiffness
        factor lies :data:`SCALE_SEEN` to :data:`MOTOR_SPAN` from 1, that factor: the motor
        side (torque constant, gear efficiency) would read the same as the pads, the data
        cannot tell which moved, and ``kf_std`` reaches past the stiffness model's estimate
        (right if the motor side moved: it does not use the current).
    adaptive_band : ndarray, optional — the adaptive filter's std as published: scaled as
        the reported filter's would be (its innovations, the held-out factor), and
        ``kf_std`` itself where it is the reported one.
    """

    kf: Array
    kf_std: Array
    kf_paper: Array
    kf_paper_nis: float
    ml_fusion: Array
    stiffness: Array
    torque_balance: Array
    adaptive: Array
    adaptive_std: Array
    stiffness_factor: Array
    stiffness_factor_std: Array
    kf_source: str = "kf"
    kf_noise_scale: float = 1.0
    kf_consistency: dict[str, Any] | None = None
    kf_filter: str = "fixed"
    motor_alike: float | None = None
    adaptive_band: Array | None = None

    @property
    def kf_switched(self) -> bool:
        """``kf`` is the adaptive-stiffness filter (the fixed filter was over-confident on
        this session, or the held-out check chose it)."""
        return self.kf_filter == "adaptive"


def estimate(
    models: ClampForceModels,
    theta: Array,
    current: Array,
    ts: float,
    *,
    factor_walk: float = 0.02,
    check: FusionCheck | None = None,
    q_scale: float | None = None,
) -> ClampForceEstimates:
    """Run all estimators on one session (no clamp-force sensor needed).

    Parameters
    ----------
    models : ClampForceModels
    theta : ndarray (K,) — motor angle, rad.
    current : ndarray (K,) — motor current, A.
    ts : float — sample time, s; must match the training.
    factor_walk : float — random-walk intensity of the stiffness factor, 1/√s.
    check : FusionCheck, optional — the training session's held-out check: the filter
        runs with its Q factor, and where the fusion did worse there than its best input
        (or the ML fusion), ``kf`` is that (its band the held-out RMSE), never a fusion
        worse than what it fuses.
    q_scale : float, optional — factor on the paper's Q, overriding the check's.
    """
    if not np.isclose(ts, models.ts, rtol=1e-3):
        raise ConfigError(f"the session is logged every {ts * 1e3:g} ms but the models were"
                          f" trained at {models.ts * 1e3:g} ms: resample it to that rate")
    ds = models.stiffness
    F_ds = ds.simulate(theta)
    F_tb = torque_balance_force(current, theta, ts, models.torque, models.window)
    F_ml = ml_fusion(F_ds, F_tb, models.sigma_ds, models.sigma_tb)
    u = ds.inputs(theta)
    if q_scale is None:
        q_scale = 1.0 if check is None else check.q_scale
    Q, R = q_scale * models.sigma_ds**2, models.sigma_tb**2
    y = F_tb[:, None]
    res = _paper_filter(ds.alpha0, u, F_ds[0], y, Q, R)
    kf_paper = res.x_filt[:, 0]
    # the session decides (no force sensor needed): the adaptive filter only where the
    # fixed one is over-confident, its innovations larger than its noise settings admit
    nu = F_tb - res.x_pred[:, 0]
    nis = float(np.nanmean(nu**2 / (res.P_pred[:, 0, 0] + R)))
    switched = nis > NIS_LIMIT or (check is not None and check.adaptive)
    ra = _adaptive_filter(ds.alpha0, u, F_ds[0], y, Q, R, factor_walk**2 * ts)
    adaptive = _band(ra, F_tb, R, check)  # its own band, reported or not
    kf, kf_std, scale, consistency = adaptive if switched else _band(res, F_tb, R, check)
    kind = "adaptive" if switched else "fixed"
    # the coloured-error smoother where the pads are the trained ones (else the adaptive
    # filter follows them)
    if check is not None and (col := check.coloured) and col.adopted and nis <= NIS_LIMIT:
        (kf, kf_std, scale, consistency), kind = _coloured(col, F_ds, F_tb, ts), "coloured"
    source = "kf" if check is None or (
        col.holds if kind == "coloured" else check.fusion_holds) else check.best_single
    if check is not None and source != "kf":
        kf = {"stiffness": F_ds, "torque_balance": F_tb, "ml_fusion": F_ml}[source]
        kf_std = np.full(theta.size, check.rmse_n[source])
    motor = (_motor_alike(ra.x_filt[:, 1], F_ds)  # where the innovations switched it
             if (kind, source) == ("adaptive", "kf") and nis > NIS_LIMIT else None)
    if motor is not None:  # the 95 % band reaches past the stiffness model's reading
        kf_std = kf_std + np.abs(kf - F_ds) / 1.96
    return ClampForceEstimates(
        kf=kf,
        kf_std=kf_std,
        kf_paper=kf_paper,
        kf_paper_nis=nis,
        ml_fusion=F_ml,
        stiffness=F_ds,
        torque_balance=F_tb,
        adaptive=ra.x_filt[:, 0],
        adaptive_std=np.sqrt(ra.P_filt[:, 0, 0]),
        stiffness_factor=ra.x_filt[:, 1],
        stiffness_factor_std=np.sqrt(ra.P_filt[:, 1, 1]),
        kf_source=source,
        kf_noise_scale=float(scale) if source == "kf" else 1.0,
        kf_consistency=consistency,
        kf_filter=kind,
        motor_alike=motor,
        adaptive_band=kf_std if motor is not None else adaptive[1],
    )


def applied_factor(factor: Array, F_ds: Array) -> float | None:
    """The adaptive filter's median stiffness factor where the brake is applied (the
    stiffness model above a tenth of its peak), None where it never is."""
    applied = F_ds > 0.1 * max(float(np.max(F_ds, initial=0.0)), 1e-9)
    return float(np.median(factor[applied])) if applied.any() else None


def _motor_alike(factor: Array, F_ds: Array) -> float | None:
    """:func:`applied_factor` where a change of the motor side would read the same
    (between :data:`SCALE_SEEN` and :data:`MOTOR_SPAN` from 1), else None. An independent
    caliper whose winding ran hotter than in training (its torque constant 11 % lower):
    the factor sat at 1.12, the adaptive filter followed the torque balance to 1.33 kN
    RMS against 0.38 for the fixed one, its band covering 35 %."""
    s = applied_factor(factor, F_ds)
    return s if s is not None and SCALE_SEEN <= abs(s - 1.0) <= MOTOR_SPAN else None


def _coloured(col: ColouredError, F_ds: Array, F_tb: Array, ts: float
              ) -> tuple[Array, Array, float, dict[str, Any]]:
    """The coloured-error smoother's mean and std (N), the factor on its variance and its
    consistency: its innovations against the held-out ones (:class:`ColouredError`),
    the band widened where the session's are larger."""
    m, phi = F_ds - F_tb, col.phi(ts)
    consistency = nis_consistency(error_filter(m, phi, col.gain)[1] ** 2 / col.innovation_var)
    scale = variance_scale(consistency)
    kf = F_ds - error_smoother(m, phi, col.gain)
    var = np.broadcast_to(col.variance(ts, smoothed_rate(kf, ts), kf), kf.shape)
    return kf, np.sqrt(var * scale), float(scale), consistency


def _paper_filter(alpha0: float, u: Array, F0: float, y: Array, Q: float, R: float
                  ) -> LinearFilterResult:
    """The paper's scalar filter: x(k+1) = α0 x(k) + u(k+1) (eq. 6, 12), z = x + v (eq. 13).

    Parameters
    ----------
    alpha0 : float — the stiffness model's force memory (eq. 6).
    u : ndarray (K,) — the stiffness model's input B u(k) (eq. 12), N.
    F0 : float — N, the initial force (the stiffness model's first value).
    y : ndarray (K, 1) — the torque balance's force (eq. 7), N.
    Q, R : float — N², process and measurement noise variances; P(0) = Q.
    """
    b = np.zeros((u.size, 1))
    b[:-1, 0] = u[1:]
    return kalman_filter_tv(
        np.array([[alpha0]]),
        np.array([[Q]]),
        np.eye(1),
        np.array([[R]]),
        np.array([F0]),
        np.array([[Q]]),
        y,
        b,
    )


def _adaptive_filter(alpha0: float, u: Array, F0: float, y: Array, Q: float, R: float,
                     q_factor: float) -> LinearFilterResult:
    """The adaptive filter: state [F, s], transition [[α0, u(k+1)], [0, 1]].

    Parameters
    ----------
    alpha0, u, F0, y, Q, R : as :func:`_paper_filter`.
    q_factor : float — variance of the stiffness factor's random walk per step (factor²).
    """
    K = u.size
    A = np.zeros((K, 2, 2))
    A[:, 0, 0] = alpha0
    A[:-1, 0, 1] = u[1:]
    A[:, 1, 1] = 1.0
    Qa = np.diag([Q, q_factor])
    return kalman_filter_tv(
        A,
        Qa,
        np.array([[1.0, 0.0]]),
        np.array([[R]]),
        np.array([F0, 1.0]),
        np.diag([Q, 0.1**2]),
        y,
    )


def _band(run: Any, F_tb: Array, R: float, check: FusionCheck | None
          ) -> tuple[Array, Array, float, dict[str, Any]]:
    """The reported filter's mean and std, the factor on its noise and its consistency.

    Q, R and P0 scaled by c leave the gain K = P H'(H P H' + R)^-1 as it is and make P
    c P: where the innovations show the filter over-confident, c is their mean NIS; the
    training session's held-out likelihood sets its least value.
    """
    consistency = nis_consistency((F_tb - run.x_pred[:, 0]) ** 2 / (run.P_pred[:, 0, 0] + R))
    scale = max(variance_scale(consistency), 1.0 if check is None else check.band_scale)
    return (run.x_filt[:, 0], np.sqrt(run.P_filt[:, 0, 0] * scale), float(scale),
            consistency)
