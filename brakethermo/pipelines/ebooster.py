"""`ebooster` pipeline: p-V and disk identification, UKF vs EKF observation, scoring.

Training (paper 004 section 3.1-3.2) on a session with the master-cylinder pressure and
pedal-force sensors: RLS with forgetting factor fits the even p-V polynomial, scipy's
trust-region-reflective least squares fits the three-slope quasi-static disk curve
(eq. 14) and the second-order disk dynamics. Observation on any session with s2 and
delta: the UKF and the EKF of the engine on the SAME model, noise and prior, each
followed by the RTS smoother (offline). Pressure channels, when present, only score.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.signal import lfilter, ss2tf

from brakethermo.config import config_dir
from brakethermo.errors import ConfigError, DataError
from brakethermo.estimation import ExtendedKalmanFilter, UnscentedKalmanFilter, urts_smooth
from brakethermo.estimation.consistency import nis_consistency, variance_scale
from brakethermo.estimation.rls import even_powers, rls_fit
from brakethermo.io.load import load_session
from brakethermo.io.session import Session
from brakethermo.models.ebooster import STATE_NAMES, BoosterFit, EboosterModel, load_fit
from brakethermo.models.rig_effects import BOOSTER_EFFECTS, RigContext
from brakethermo.numeric import noise_std, rmse
from brakethermo.pipelines.rig_carry import carried, carried_prediction
from brakethermo.pipelines.rig_checks import (
    LOW_COVERAGE,
    MIN_APPLIED,
    Expect,
    channel_warnings,
    check_rig_channels,
    in_band,
)
from brakethermo.results.ebooster import (
    OBSERVERS,
    PRESSURES,
    EboosterResult,
    ObserverTrack,
)
from brakethermo.rigs.booster import (
    PV_POWERS,
    discretise,
    disk_quasi_static,
    disk_transfer,
    leverage_force,
    pv_pressure,
)
from brakethermo.rigs.booster_datasheet import BoosterSpec, load_booster
from brakethermo.rigs.pv_curve import (
    candidate_names,
    choose_curve,
    fit_knots,
    knots_for,
    knots_pressure,
)
from brakethermo.rigs.signals import SPEED_WINDOW_S, smoothed_rate

Array = NDArray[np.float64]
S2, DELTA = "pushrod_displacement", "reaction_disk_delta"
PEDAL = "pedal_force"
CHANNELS = (S2, DELTA, *PRESSURES.values(), PEDAL)
DEFAULT_FIT = "ebooster_fit"  # configs/rigs/ebooster_fit.toml, trained on a simulated bench
MM, MPA = 1e3, 1e-6  # SI -> model units
APPLIED_MPA = 0.2  # a pressure above this: the brake is applied (coverage while braking)


def _series(session: Session, name: str, scale: float, *, gaps: bool) -> Array:
    """A channel in model units; NaN inside gaps refused unless ``gaps``."""
    v = session.values(name) * scale
    if not gaps and not np.isfinite(v).all():
        bad = np.flatnonzero(~np.isfinite(v))
        raise DataError(
            f"has no samples from t = {session.time[bad[0]]:.3f} s ({bad.size} grid points); "
            "the observer needs this input at every step: cut the session or fill the gap",
            path=session.path, channel=name,
        )
    return v


def _expect(training: bool) -> tuple[Expect, ...]:
    """What a booster's channels look like (SI); pressures and the pedal force are inputs
    of the training and only score the observer otherwise."""
    role: Literal["input", "score"] = "input" if training else "score"
    return (Expect(S2, "m", 0.1, positive=True, measured=False), Expect(DELTA, "m", 0.01),
            *(Expect(ch, "Pa", 3e7, positive=True, role=role) for ch in PRESSURES.values()),
            Expect(PEDAL, "N", 5e3, positive=True, role=role))


def load_booster_session(path: str | Path, aliases: str | Path | None = None, *,
                         training: bool = False) -> Session:
    """Load a booster session on its native grid and check its channels (the observer's
    inputs refuse the run; a scoring channel gets a warning in ``session.warnings``)."""
    session = load_session(path, rate_hz=None, channels=CHANNELS, aliases=aliases)
    session.require(S2, DELTA)
    lacking = [ch for ch in (PRESSURES["p_m"], PEDAL) if training and not session.has(ch)]
    if lacking:
        raise DataError(
            f"has no {' or '.join(lacking)}: a training session (--train) must carry the"
            " master-cylinder pressure sensor and the pedal force (the p-V curve is fitted to"
            " the one, the reaction disk to the other); train on a bench run with both, or"
            " give a saved fit with --fit (if the file logs them under other names, map"
            f" them with --aliases FILE; it has: {', '.join(session.available)})",
            path=session.path)
    if len(session.frame) < 10:
        raise DataError("holds fewer than 10 samples; record a longer session",
                        path=session.path)
    notes = check_rig_channels(session, _expect(training))
    return replace(session, warnings=(*session.warnings, *notes)) if notes else session


def train(path: str | Path, spec: BoosterSpec, aliases: str | Path | None = None) -> BoosterFit:
    """Identify the p-V curve and the reaction disk from a training session, and the
    observers' process noise by held-out likelihood (:func:`choose_q_factor`).

    Parameters
    ----------
    path : str or Path — session with s2, delta, master-cylinder pressure and pedal force.
    spec : BoosterSpec

    Returns
    -------
    BoosterFit
    """
    session = load_booster_session(path, aliases, training=True)
    fit = fit_training(session, spec)
    factor, nats = choose_q_factor(session, spec)
    return replace(fit, q_factor=factor, q_heldout_nats=nats)


# Factors on the datasheet's process noise tried on the training session's halves, and
# the gain in held-out log-likelihood per reading another must show to replace 1.
Q_FACTORS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)
Q_MARGIN_NATS = 0.02


def _halves(session: Session) -> tuple[Session, Session] | None:
    """The session cut where the screw is furthest back in its middle third (between two
    sweeps, when it holds two), or None when it is too short to cut."""
    s2 = _series(session, S2, MM, gaps=False)
    K = s2.size
    if K < 60:
        return None
    mid = K // 3 + int(np.argmin(s2[K // 3: 2 * K // 3]))
    frame = session.frame
    return (replace(session, frame=frame.iloc[:mid].reset_index(drop=True)),
            replace(session, frame=frame.iloc[mid:].reset_index(drop=True)))


def choose_q_factor(session: Session, spec: BoosterSpec) -> tuple[float, tuple[float, ...]]:
    """The process-noise factor the training session's pressure sensor supports.

    Trained on one half, observed on the other (both ways): for each factor of
    :data:`Q_FACTORS` on the datasheet's noise of the physical states, the UKF's filtered
    p_m is scored by the Gaussian log-likelihood of the measured pressure (its variance
    plus the sensor's own noise from its first differences). The datasheet's Q (factor
    1) stays unless a larger one beats it by :data:`Q_MARGIN_NATS` per reading — never a
    smaller one: a slow sweep cannot show that the datasheet's is too much. Returns the
    factor and the mean log-likelihood per reading of each factor (``()``: the session
    cannot be cut into two halves a fit can be trained on; the factor is then 1).
    """
    halves = _halves(session)
    if halves is None:
        return 1.0, ()
    total = np.zeros(len(Q_FACTORS))
    count = 0
    for train_part, test_part in (halves, halves[::-1]):
        try:
            fit = fit_training(train_part, spec)
        except DataError:
            return 1.0, ()  # a half that does not sweep the pressure range
        s2 = _series(test_part, S2, MM, gaps=False)
        delta = _series(test_part, DELTA, MM, gaps=True)
        p_m = _series(test_part, PRESSURES["p_m"], MPA, gaps=True)
        sensor_var = noise_std(p_m) ** 2
        read = np.isfinite(p_m)
        count += int(read.sum())
        for i, c in enumerate(Q_FACTORS):
            model = EboosterModel(spec, replace(fit, q_factor=c), s2, test_part.dt)
            x0, P0 = model.prior(float(delta[0]))
            res = _observer(model, "ukf").run(x0, P0, delta[:, None], store="diag")
            var = np.clip(res.var_filt[read, 0], 0.0, None) + sensor_var
            err = p_m[read] - res.x_filt[read, 0]
            # every reading scored for every factor: one whose filter lost a step loses
            total[i] += float(np.sum(-0.5 * (np.log(2.0 * np.pi * var) + err**2 / var)))
    if count == 0:
        return 1.0, ()
    nats = np.where(np.isfinite(total), total / count, np.nan)
    if not np.isfinite(nats).any():  # every factor lost its track: fit_warnings says so
        return 1.0, tuple(float(v) for v in nats)
    one = nats[Q_FACTORS.index(1.0)]
    base = one if np.isfinite(one) else -np.inf  # the datasheet's lost: any other is better
    # a slow training sweep can show that the model needs more noise, not that the
    # datasheet's is too much: it holds none of the fast applies where the model errs
    # (an independent bench's p-V curve fitted closely chose 0.25, and the UKF lost its
    # track on a vehicle session)
    allowed = np.where([c >= 1.0 for c in Q_FACTORS], nats, np.nan)
    if not np.isfinite(allowed).any():  # only factors below the datasheet's kept track
        return 1.0, tuple(float(v) for v in nats)
    best = int(np.nanargmax(allowed))
    chosen = Q_FACTORS[best] if nats[best] > base + Q_MARGIN_NATS else 1.0
    return chosen, tuple(float(v) for v in nats)  # NaN: a factor whose filter lost a step


def fit_training(session: Session, spec: BoosterSpec) -> BoosterFit:
    """The p-V curve (RLS, eq. 12) and the reaction disk (eq. 14) of a loaded training
    session (DataError when it lacks the sensors or the screw travel)."""
    session.require(PRESSURES["p_m"], PEDAL)
    s2 = _series(session, S2, MM, gaps=False)
    travel = float(np.max(s2) - np.min(s2))
    if travel < spec.min_travel_mm:
        raise DataError(
            f"the screw moves only {travel:.3f} mm (less than {spec.min_travel_mm:g} mm): a "
            "training session must sweep the pressure range at constant speed up and down",
            path=session.path, channel=S2,
        )
    p_m = _series(session, PRESSURES["p_m"], MPA, gaps=True)
    f_in = _series(session, PEDAL, 1.0, gaps=True)
    delta = _series(session, DELTA, MM, gaps=True)
    ok = np.isfinite(p_m) & np.isfinite(f_in) & np.isfinite(delta)
    # p-V: RLS on [u^2, u^4, u^6, u^8], u = s2 / stroke (eq. 12), or a piecewise-linear
    # curve where that predicts held-out training data better (rigs.pv_curve)
    w = rls_weights(s2[ok], p_m[ok], spec)
    knots, values, heldout = pv_candidates(s2[ok], p_m[ok], spec)
    pv_res = p_m[ok] - (knots_pressure(s2[ok], knots, values) if knots.size else
                        even_powers(s2[ok] / spec.stroke_mm, PV_POWERS) @ w)
    # disk: net force from the leverage (eq. 10) with the measured pedal force
    force = leverage_force(p_m, s2, f_in, spec.area_mm2, spec.return_spring_n_per_mm,
                           spec.area_ratio)
    _refuse_reversed(force, delta, session.path, "the net disk force (eq. 10)")
    disk, omega_n, damping, tau_z, disk_rmse = _fit_disk(force, delta, ok, session.dt)
    dof = spec.pedal_dof
    return BoosterFit(
        pv_coeffs=tuple(float(v) for v in w),  # type: ignore[arg-type]
        stroke_mm=spec.stroke_mm,
        disk=disk,
        omega_n=omega_n,
        damping=damping,
        tau_z=tau_z,
        pedal_scale_n=float(np.mean(np.clip(f_in[ok], 0.0, None)) / dof),
        train_session=str(session.path),
        pv_rmse_mpa=rmse(pv_res),
        s2_max_mm=float(np.max(s2[ok])),
        disk_rmse_mm=disk_rmse,
        pv_knots_mm=tuple(float(v) for v in knots),
        pv_knot_mpa=tuple(float(v) for v in values),
        pv_heldout_mpa=heldout,
    )


def _pv_choice(fit: BoosterFit) -> str:
    """The p-V candidates' held-out RMSE in words."""
    return ", ".join(f"{n} {v:.3f} MPa" for n, v in zip(candidate_names(), fit.pv_heldout_mpa,
                                                         strict=True))


def rls_weights(s2: np.ndarray, p_m: np.ndarray, spec: BoosterSpec) -> np.ndarray:
    """The paper's p-V polynomial (eq. 12): RLS weights (MPa) of [u^2, u^4, u^6, u^8],
    u = s2 / stroke, on training samples (mm, MPa, in time order)."""
    return rls_fit(even_powers(s2 / spec.stroke_mm, PV_POWERS), p_m, lam=spec.forgetting,
                   delta=spec.rls_delta).w


def pv_candidates(s2: np.ndarray, p_m: np.ndarray, spec: BoosterSpec
                  ) -> tuple[np.ndarray, np.ndarray, tuple[float, ...]]:
    """The p-V curve :func:`~brakethermo.rigs.pv_curve.choose_curve` picks on training
    samples (mm, MPa, in time order): its knots (mm) and pressures (MPa), both empty for
    the paper's polynomial, and every candidate's held-out RMSE (MPa)."""
    def polynomial(s: np.ndarray, p: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        w = rls_weights(s, p, spec)
        return lambda x: pv_pressure(x, w, spec.stroke_mm, float(np.max(s)))

    count, heldout = choose_curve(s2, p_m, polynomial)
    if count == 0:
        return np.zeros(0), np.zeros(0), heldout
    knots = knots_for(s2, p_m, count)
    return knots, fit_knots(s2, p_m, knots), heldout


SHIPPED_FIT_NOTE = (
    "no training of this booster: the training result shipped for the bench datasheet"
    " (fitted on a simulated session) was used, and a booster's own can be far from it (an"
    " independent bench's vehicle session: 1.6 MPa RMS with it, 0.14 with its own"
    " training) — train on a session of this booster (--train, or --fit with a saved"
    " result)")
SLOPE_MAX = 0.1  # mm/N, the disk curve's slopes fitted within [0, SLOPE_MAX]
DYNAMICS_RANGE = {"omega_n": (1.0, 2000.0), "damping": (0.05, 5.0), "tau_z": (0.0, 1.0)}
POOR_NATS = -10.0  # nats per held-out reading: no factor predicts the other half (ours 1-3)
LOST_NATS = -1e6  # held-out log-likelihood of a training half no filter that kept its track gives


def fit_warnings(fit: BoosterFit) -> list[str]:
    """What a training result cannot support, in words: disk parameters fitted at the edge
    of their range (the training never moved them), a rigid stretch of the disk curve
    (no slope: delta says nothing of the force there), and process-noise factors whose
    filter lost its track on held-out halves of the training session."""
    out = []
    # within 1 % of a bound (a zero bound is an absent term, a fit's own answer)
    edge = [f"{k} = {getattr(fit, k):.3g}" for k, bounds in DYNAMICS_RANGE.items()
            if any(b != 0.0 and abs(getattr(fit, k) - b) <= 0.01 * abs(b) for b in bounds)]
    if edge:
        out.append("the reaction disk's dynamics were fitted at the edge of their range ("
                   + ", ".join(edge) + "): the training session did not move them, or the"
                   " paper's disk model does not describe this disk (its fit leaves"
                   f" {fit.disk_rmse_mm:.3g} mm RMS of delta; an independent bench's disk,"
                   " moved by pedal waves, left 0.13-0.18 mm): the observers then take"
                   " little from delta")
    flat = [i + 1 for i, slope in enumerate(fit.disk[2:]) if slope <= 1e-6 * SLOPE_MAX]
    if flat:
        where = (f"below {fit.disk[0]:.0f} N" if flat[0] == 1 else
                 f"above {fit.disk[flat[0] - 2]:.0f} N")
        out.append(f"the reaction disk's curve has no slope {where} (segment {flat[0]}): delta"
                   " says nothing of the force there, and the observers' pressures rest on"
                   " the p-V curve alone")
    lost = [f"{q:g}" for q, n in zip(Q_FACTORS, fit.q_heldout_nats, strict=False)
            if not np.isfinite(n) or n < LOST_NATS]
    if lost:
        out.append("on held-out halves of the training session the filter lost its track"
                   " with the process noise times " + ", ".join(lost) + f" (it runs with"
                   f" {fit.q_factor:g}): this training result makes a fragile observer;"
                   " train on a longer session that sweeps the pressures at constant speed")
    nats = np.array(fit.q_heldout_nats, float)
    if nats.size and np.isfinite(nats).any() and np.nanmax(nats) < POOR_NATS:
        out.append(f"on held-out halves of the training session every process noise tried"
                   f" predicts the pressure poorly (at best {np.nanmax(nats):.0f} nats per"
                   " reading): halves that differ — one sweep cut into its way up and its"
                   " way down — teach little about each other; train on a session of"
                   " several sweeps up and down")
    if out:
        out = [f"training {Path(fit.train_session).name}: {w}" for w in out]
    return out


# delta against the disk compression the leverage (eq. 10) predicts from the pedal force
# and p_m correlates +0.93 to +0.99 on the benches (vehicle, open-loop, training sessions)
# and -0.93 to -0.99 with delta negated; below -0.5 the sign is reversed, not noise.
REVERSED_CORRELATION = -0.5


def _refuse_reversed(compression: Array, delta: Array, path: Path, what: str) -> None:
    """Refuse a delta (mm) that falls where ``compression`` (any unit, same sign as the
    disk's compression) rises: the channel's sign is reversed (DataError)."""
    ok = np.isfinite(compression) & np.isfinite(delta)
    if ok.sum() < 10 or np.std(compression[ok]) == 0.0 or np.std(delta[ok]) == 0.0:
        return
    r = float(np.corrcoef(compression[ok], delta[ok])[0, 1])
    if r < REVERSED_CORRELATION:
        raise DataError(
            f"falls where {what} says the reaction disk is compressed (correlation {r:.2f};"
            " +0.9 or more on a booster logged right): its sign is reversed; negate the"
            " channel in the file and run again", path=path, channel=DELTA)


def _refuse_reversed_delta(session: Session, s2: Array, delta: Array, fit: BoosterFit,
                           spec: BoosterSpec) -> None:
    """Check delta's sign against the training's disk fit, where the session logs the
    pedal force and p_m and neither got a warning of its own (a reversed pedal force
    is said by its own check, and would point at delta here)."""
    p_ch = PRESSURES["p_m"]
    if not (session.has(PEDAL) and session.has(p_ch)) or any(
            channel_warnings(session, ch) for ch in (PEDAL, p_ch)):
        return
    force = leverage_force(_series(session, p_ch, MPA, gaps=True), s2,
                           _series(session, PEDAL, 1.0, gaps=True), spec.area_mm2,
                           spec.return_spring_n_per_mm, spec.area_ratio)
    _refuse_reversed(disk_quasi_static(force, np.array(fit.disk)), delta, session.path,
                     f"the training's disk fit with this session's {PEDAL} and {p_ch}")


def _disk_response(u: Array, omega_n: float, damping: float, tau_z: float, dt: float) -> Array:
    """delta from the quasi-static compression u through the discretised disk dynamics."""
    A, B = disk_transfer(omega_n, damping, tau_z)
    Ad, Bd = discretise(A, B, dt)
    b, a = ss2tf(Ad, Bd[:, None], np.array([[1.0, 0.0]]), np.zeros((1, 1)))
    zi = np.zeros(2)
    # start at rest on the quasi-static curve: the steady state of the filter at u[0]
    y, _ = lfilter(b[0], a, u - u[0], zi=zi)
    return y + u[0]


def _fit_disk(
    force: Array, delta: Array, ok: Array, dt: float
) -> tuple[tuple[float, float, float, float, float], float, float, float, float]:
    """Three-slope quasi-static curve (eq. 14), then the two-pole one-zero dynamics."""
    fabs = np.abs(force[ok])
    dsign = np.sign(force[ok]) * delta[ok]
    # quasi-static points: where the net force changes slowly
    rate = np.abs(np.gradient(force[ok], dt))
    slow = rate <= np.quantile(rate, 0.3)
    fmax = float(np.quantile(fabs, 0.99))

    def curve(theta: Array, x: Array) -> Array:
        p1, gap, p3, p4, p5 = theta
        return disk_quasi_static(x, np.array([p1, p1 + gap, p3, p4, p5]))

    theta0 = np.array([0.2 * fmax, 0.3 * fmax, 0.005, 0.003, 0.0015])
    qs = least_squares(
        lambda th: curve(th, fabs[slow]) - dsign[slow], theta0, method="trf",
        bounds=([0.0, 1.0, 0.0, 0.0, 0.0], [fmax, fmax, *(3 * (SLOPE_MAX,))]),
    )
    p1, gap, p3, p4, p5 = (float(v) for v in qs.x)
    disk = (p1, p1 + gap, p3, p4, p5)
    u = np.zeros_like(force)
    u[ok] = disk_quasi_static(force[ok], np.array(disk))
    u = np.interp(np.arange(u.size), np.flatnonzero(ok), u[ok])
    target = np.where(ok, delta, 0.0)
    skip = min(int(0.5 / dt), u.size // 4)

    def resid(th: Array) -> Array:
        y = _disk_response(u, th[0], th[1], th[2], dt)
        return (y - target)[skip:][ok[skip:]]

    dyn = least_squares(resid, np.array([60.0, 0.8, 0.01]), method="trf",
                        bounds=tuple(zip(*DYNAMICS_RANGE.values(), strict=True)),
                        x_scale=[60, 1, 0.01])
    return disk, float(dyn.x[0]), float(dyn.x[1]), float(dyn.x[2]), rmse(dyn.fun)


def booster_context(session: Session, s2: Array, fit: BoosterFit) -> RigContext:
    """What the booster's candidate effects see of a session: s2 (mm), its speed (mm/s,
    a 20 ms moving average), time from the start (s) and the fit's p-V curve."""
    return RigContext(s2, smoothed_rate(s2, session.dt, SPEED_WINDOW_S),
                      session.time - session.time[0], fit.pressure)


def static_pressure_carried(text: str, session: Session, s2: Array, fit: BoosterFit,
                            diagnose: Any) -> tuple[Array | None, dict[str, Any] | None]:
    """The static pressure (MPa per step) under the effects ``--with-effect`` carries
    (:mod:`brakethermo.pipelines.rig_carry`), None when nothing is carried."""
    chosen, fact = carried(text, BOOSTER_EFFECTS, "ebooster", diagnose)
    if not chosen:
        return None, fact
    pv = carried_prediction(BOOSTER_EFFECTS, chosen, booster_context(session, s2, fit))
    return np.clip(pv, 0.0, None), fact


DEFAULT_SOURCE = ("default: this session logs the master-cylinder pressure, so it is"
                  " diagnosed first (auto)")
IN_SAMPLE = ("this session's pressure sensor placed the curve (on its fitting applies) and"
             " scores p_m: pressure_rmse_mpa.p_m and the coverage against it are partly"
             " in-sample; p_f and p_r are not measured by it")
REST_OFFSET_MPA = 0.3  # MPa a master cylinder may read at rest (a transducer's zero)
REST_TRAVEL_MM = 0.2  # mm of screw travel that count as at rest
SHIFT_SD_PLAUSIBLE = 3.0  # x the datasheet's: a session's own curve spread beyond is suspect


def carry(with_effect: str | None, session: Session, s2: Array, fit: BoosterFit,
          bench: str | Path, aliases: str | Path | None
          ) -> tuple[Array | None, dict[str, Any] | None, float | None]:
    """What the observers carry: the static pressure under ``--with-effect`` (None: the
    curve as trained), its fact, and the session's own held-out p-V residual (MPa) when a
    diagnosis of this session measured it, else None.

    By default (``with_effect`` None) a session that logs the master-cylinder pressure is
    diagnosed first ('auto'): a real booster's curve sits 0.2-0.4 mm along the stroke from
    the training day's, which delta cannot resolve and the pressure sensor can, on
    held-out applies. The default then trusts that sensor (a gain error moves the curve
    with it), so a sensor its channel check flagged is not used, and where the diagnosis
    cannot run (too few applies) the curve is carried as trained; the fact says why.
    """
    found: dict[str, Any] = {}

    def diagnose() -> dict[str, Any]:
        from brakethermo.pipelines.diagnose.rig import diagnose_booster

        found.update(diagnose_booster(session.path, bench=bench, aliases=aliases,
                                      fit=fit).summary)
        return found

    if with_effect is not None:
        pv, fact = static_pressure_carried(with_effect, session, s2, fit, diagnose)
        return pv, fact, heldout_curve_sd(found)
    channel = PRESSURES["p_m"]
    if not session.has(channel):
        return None, None, None
    suspect = channel_warnings(session, channel)
    rest = _rest_reading(session, s2)
    if rest is not None and abs(rest) > REST_OFFSET_MPA:
        suspect.append(f"it reads {rest:+.2f} MPa with the screw back at rest, where a"
                       " master cylinder holds no pressure: an offset or a unit fault")
    if suspect:
        return None, _skipped(f"its pressure sensor is suspect ({suspect[0]})"), None
    try:
        diagnose()
    except DataError as exc:
        return None, _skipped(f"its diagnosis cannot run ({exc.detail})"), None
    pv, fact = static_pressure_carried("auto", session, s2, fit, lambda: found)
    assert fact is not None  # auto always states what it carried
    fact["source"] = DEFAULT_SOURCE
    fact["in_sample"] = IN_SAMPLE
    return pv, fact, heldout_curve_sd(found)


def _rest_reading(session: Session, s2: Array) -> float | None:
    """MPa: the median master-cylinder pressure with the screw back at rest (None when the
    session never rests, or logs no pressure there)."""
    p_m = _series(session, PRESSURES["p_m"], MPA, gaps=True)
    rest = (s2 < REST_TRAVEL_MM) & np.isfinite(p_m)
    return float(np.median(p_m[rest])) if rest.sum() >= 10 else None


def _skipped(why: str) -> dict[str, Any]:
    """The default's fact when it does not diagnose a session that logs the pressure."""
    return {"source": DEFAULT_SOURCE, "verdict": "none", "verdict_set": [], "effects": {},
            "skipped": why, "note": f"the curve as trained: {why}"}


def heldout_curve_sd(diagnosis: dict[str, Any]) -> float | None:
    """MPa: the held-out RMS of the session's pressures about the static curve the observers
    carry — the carried effect's ``rmse_after``, or the gap's with nothing carried; None
    without a diagnosis of this session."""
    if not diagnosis:
        return None
    entry = next((e for e in diagnosis.get("effects") or []
                  if e.get("name") == diagnosis.get("verdict")), None)
    value = entry["rmse_after"] if entry is not None else (diagnosis.get("gap") or {}).get("rmse")
    return float(value) if value is not None and np.isfinite(value) else None


def band_shift_sd(model: EboosterModel, curve_sd: float | None
                  ) -> tuple[float, str, str | None]:
    """mm: the 1 sigma of the curve's place along the stroke the pressure bands admit,
    where it comes from (``"datasheet"`` or ``"session"``), and a warning or None.

    The session's own held-out RMS about its curve (MPa), where a diagnosis measured it,
    as the shift that explains it at the curve's slopes while applied (the band is then
    nil at rest and grows with the slope, as the datasheet's); the datasheet's
    ``pv_shift_sd_mm`` otherwise, and where the session's would be more than
    :data:`SHIFT_SD_PLAUSIBLE` times it (a sensor whose unit or gain is off, not a
    curve: it is said).
    """
    spec = model.spec
    if curve_sd is None:
        return spec.pv_shift_sd_mm, "datasheet", None
    slope = pv_slope(model)
    applied = model.fit.pressure(np.clip(model.s2, 0.0, None)) > APPLIED_MPA
    rms = float(np.sqrt(np.mean(slope[applied] ** 2))) if applied.any() else 0.0
    shift = curve_sd / rms if rms > 0.0 else float("inf")
    if shift <= SHIFT_SD_PLAUSIBLE * spec.pv_shift_sd_mm:
        return shift, "session", None
    return spec.pv_shift_sd_mm, "datasheet", (
        f"this session's pressures sit {curve_sd:.3g} MPa RMS about its curve on held-out"
        f" applies, {shift:.3g} mm of shift at its slopes, beyond what a curve's place does"
        f" ({SHIFT_SD_PLAUSIBLE:g}x the datasheet's {spec.pv_shift_sd_mm:g} mm): its"
        " pressure sensor or its unit is suspect")


def _band(shift_sd: float, source: str, curve_sd: float | None) -> dict[str, Any]:
    """``summary.json`` ``band``: what the pressure bands hold."""
    where = ("this session's own held-out RMS about the curve carried (its diagnosis on"
             " held-out applies), as a shift at the curve's slopes while applied"
             if source == "session" else
             "the datasheet's shift: where this session's curve sits against the training"
             " session's, which delta cannot resolve (it trades against the pedal force)")
    return {"pv_shift_sd_mm": shift_sd, "shift_sd_from": source,
            "heldout_curve_sd_mpa": curve_sd,
            "contains": "the filter's (smoother's) own spread, times noise_scale where its"
                        " innovations show it over-confident (their mean NIS), widened for the"
                        " pressures by the p-V curve's slope times pv_shift_sd_mm: " + where}


def default_fit_path() -> Path:
    """The shipped training result."""
    return config_dir() / "rigs" / f"{DEFAULT_FIT}.toml"


def pv_slope(model: EboosterModel) -> Array:
    """MPa/mm per step: the trained p-V curve's slope at the screw position."""
    eps = 0.05  # mm
    curve = model.fit.pressure
    s2 = np.clip(model.s2, 0.0, None)
    return (curve(s2 + eps) - curve(np.clip(s2 - eps, 0.0, None))) / (
        s2 + eps - np.clip(s2 - eps, 0.0, None))


def pv_position_var(model: EboosterModel, shift_sd_mm: float | None = None) -> Array:
    """MPa^2 per step: what not knowing where the session's p-V curve sits adds.

    The curve's slope at the screw position times a 1 sigma of the curve's shift along the
    stroke (mm; default the datasheet's ``pv_shift_sd_mm``); delta cannot resolve the
    shift (it trades against the pedal force), so it widens the pressure bands instead of
    being a state.
    """
    sd = model.spec.pv_shift_sd_mm if shift_sd_mm is None else shift_sd_mm
    return (pv_slope(model) * sd) ** 2


def gauge_pressure(mean: Array, var: Array) -> tuple[Array, Array]:
    """The filter's pressure estimate constrained to a gauge pressure >= 0, MPa and MPa^2.

    A brake circuit holds no negative gauge pressure worth the name; where the filter's
    Gaussian mean sits below zero (after a release, when delta says little) the reported
    pressure is the most probable value of that Gaussian truncated at zero — zero — and
    the band keeps the filter's spread.
    """
    return np.maximum(mean, 0.0), var


def _observer(model: EboosterModel, which: str) -> UnscentedKalmanFilter | ExtendedKalmanFilter:
    """The UKF or the EKF on ``model``, with its noise and the bench's sigma-point spread."""
    s = model.spec
    Q, R = model.Q_of_step(), model.R()
    if which == "ukf":
        return UnscentedKalmanFilter(model.f, Q, R, H=model.H, alpha=s.alpha, beta=s.beta,
                                     kappa=s.kappa)
    return ExtendedKalmanFilter(model.f, Q, R, H=model.H)


def _run(model: EboosterModel, which: str, y: Array, smooth: bool,
         curve_var: Array | None = None) -> ObserverTrack:
    """One observer over the session; ``curve_var`` (MPa^2 per step) is what the place of
    the session's p-V curve adds to the pressure bands (default :func:`pv_position_var`)."""
    x0, P0 = model.prior(float(y[0]))  # prior() starts a gap at delta = 0
    t0 = time.perf_counter()
    res = _observer(model, which).run(x0, P0, y[:, None], store="smoother" if smooth else "diag")
    if smooth:
        sm = urts_smooth(res)
        x, var = sm.x_smooth, sm.var_smooth
    else:
        x, var = res.x_filt, res.var_filt
    seconds = time.perf_counter() - t0
    consistency = nis_consistency(res.nis, res.n_obs, res.innovation)
    scale = variance_scale(consistency)  # its innovations larger than its noise admits
    var = np.clip(var[:, :5], 0.0, None) * scale
    var[:, :3] += (pv_position_var(model) if curve_var is None else curve_var)[:, None]
    x = x[:, :5].copy()
    x[:, :3], var[:, :3] = gauge_pressure(x[:, :3], var[:, :3])
    return ObserverTrack(
        x=x, std=np.sqrt(var),
        residual=res.innovation[:, 0], filt=res, smoothed=smooth, seconds=seconds,
        consistency=consistency, noise_scale=scale,
    )


# No brake circuit holds this (hoses burst near 70 MPa; circuits run to about 20)
MAX_PRESSURE_MPA = 50.0


def lost_track(track: ObserverTrack, delta: Array, time_s: Array) -> str:
    """Why an observer's estimate cannot be a booster's, in words ('' when it can): a
    state not finite, a pressure beyond :data:`MAX_PRESSURE_MPA`, or a disk travel zeta1
    beyond ten times the largest measured |delta| plus 1 mm."""
    x = track.x
    span = float(np.nanmax(np.abs(delta))) if np.isfinite(delta).any() else 1.0
    tests = (("not finite", ~np.isfinite(x).all(axis=1)),
             (f"pressures beyond {MAX_PRESSURE_MPA:g} MPa",
              np.abs(np.nan_to_num(x[:, :3])).max(axis=1) > MAX_PRESSURE_MPA),
             (f"disk travel beyond {10.0 * span + 1.0:.3g} mm",
              np.abs(np.nan_to_num(x[:, 3])) > 10.0 * span + 1.0))
    failed = [(what, bad) for what, bad in tests if bad.any()]
    if not failed:
        return ""
    k = min(int(np.argmax(bad)) for _, bad in failed)
    worst = float(np.max(np.abs(np.nan_to_num(x[:, :3], posinf=0.0, neginf=0.0))))
    return (f"from t = {time_s[k] - time_s[0]:.2f} s: " + ", ".join(w for w, _ in failed)
            + f" (pressures up to {worst:.3g} MPa), {track.filt.n_repairs} covariance"
            " repairs")


def _withdrawn(track: ObserverTrack) -> ObserverTrack:
    """The track with its estimates and bands empty (NaN): the page shows none of them."""
    empty = np.full_like(track.x, np.nan)
    return replace(track, x=empty, std=empty.copy(),
                   residual=np.full_like(track.residual, np.nan))


def _rmse(a: Array) -> float | None:
    """RMS of the finite samples, None when there is none (a figure the page leaves out)."""
    value = rmse(a)
    return value if np.isfinite(value) else None


def observe(
    path: str | Path,
    *,
    train_path: str | Path | None = None,
    fit_path: str | Path | None = None,
    bench: str | Path = "ebooster",
    aliases: str | Path | None = None,
    smooth: bool = True,
    with_effect: str | None = None,
) -> EboosterResult:
    """Run both observers on a session and score them.

    Parameters
    ----------
    path : session to observe (needs s2 and delta).
    train_path : training session; else ``fit_path``; else the shipped training result.
    fit_path : a training result TOML written earlier.
    bench : bench datasheet id or TOML.
    aliases : channel alias TOML.
    smooth : run the RTS smoother after each filter (offline use).
    with_effect : the p-V departure a diagnosis found, carried into both observers:
        'none', 'auto' (diagnose this session: needs the pressure sensor), a
        diagnosis.json or NAME=VALUE (:mod:`brakethermo.pipelines.rig_carry`); ``None``
        (the default): 'auto' where the session logs the master-cylinder pressure, else
        'none' (:func:`carry`).

    Returns
    -------
    EboosterResult
    """
    if train_path is not None and fit_path is not None:
        raise ConfigError("--train and --fit both given: the observer runs on one p–V and disk"
                          " fit; give the training session or a saved fit, not both")
    spec = load_booster(bench)
    t_start = time.perf_counter()
    shipped = train_path is None and fit_path is None
    if train_path is not None:
        fit = train(train_path, spec, aliases)
    else:
        fit = load_fit(fit_path or default_fit_path())
    t_train = time.perf_counter() - t_start
    session = load_booster_session(path, aliases)
    s2 = _series(session, S2, MM, gaps=False)
    delta = _series(session, DELTA, MM, gaps=True)
    if not np.isfinite(delta).any():
        raise DataError("holds no finite sample", path=session.path, channel=DELTA)

    _refuse_reversed_delta(session, s2, delta, fit, spec)
    pv, carried_fact, curve_sd = carry(with_effect, session, s2, fit, bench, aliases)
    model = EboosterModel(spec, fit, s2, session.dt, pv=pv)
    shift_sd, shift_from, shift_warning = band_shift_sd(model, curve_sd)
    curve_var = pv_position_var(model, shift_sd)
    tracks = {which: _run(model, which, delta, smooth, curve_var) for which in OBSERVERS}
    lost = {w: why for w in OBSERVERS if (why := lost_track(tracks[w], delta, session.time))}
    if len(lost) == len(OBSERVERS):
        raise DataError(
            "both observers lost their track (" + "; ".join(f"{w.upper()} {why}" for w, why
                                                          in lost.items())
            + "): the training result does not hold for this session — retrain on a"
            " session of this booster that sweeps its pressures, or check the units of s2"
            " and delta", path=session.path, channel=DELTA)
    noise_warning = _beyond_noise(tracks, lost, session.path, fit.train_session)
    tracks = {w: _withdrawn(t) if w in lost else t for w, t in tracks.items()}
    validation = _validation(session)
    summary = _summary(session, spec, fit, tracks, validation, smooth, t_train, s2)
    summary["band"] = _band(shift_sd, shift_from, curve_sd)
    summary["warnings"] += [w for w in (shift_warning, noise_warning) if w]
    summary["with_effect"] = carried_fact
    summary["lost_track"] = lost
    summary["warnings"] += fit_warnings(fit) + ([SHIPPED_FIT_NOTE] if shipped else [])
    summary["warnings"] += [
        f"IMPLAUSIBLE RESULT: the {w.upper()} lost its track ({why}); its estimates are"
        f" withdrawn (empty) and the {other.upper()}'s stand" for w, why in lost.items()
        for other in OBSERVERS if other != w]
    return EboosterResult(session, spec, fit, session.time, s2, delta, validation, tracks,
                          summary)


def _validation(session: Session) -> dict[str, Array]:
    """The session's pressure sensors (MPa) the observers are scored against, by state. A
    channel its own check warned about scores nothing: its figures would mean nothing (a
    bar sensor labelled MPa printed a p_m RMSE of 45.8 MPa, and a coverage warning sent
    the user to diagnose and retraining)."""
    return {state: _series(session, ch, MPA, gaps=True)
            for state, ch in PRESSURES.items()
            if session.has(ch) and not channel_warnings(session, ch)}


def _summary(
    session: Session, spec: BoosterSpec, fit: BoosterFit, tracks: dict[str, ObserverTrack],
    validation: dict[str, Array], smooth: bool, t_train: float, s2: Array,
) -> dict[str, Any]:
    res = {w: _rmse(tracks[w].residual) for w in OBSERVERS}
    improvement = None
    if res["ekf"] and res["ukf"] is not None:
        improvement = 100.0 * (res["ekf"] - res["ukf"]) / res["ekf"]
    scores = {w: _pressure_scores(tracks[w], validation) for w in OBSERVERS}
    p_rmse = {w: sc.rmse_mpa for w, sc in scores.items()}
    cov95 = {w: sc.coverage_95 for w, sc in scores.items()}
    cov95_braking = {w: sc.coverage_95_braking for w, sc in scores.items()}
    out1 = {w: sc.outside_1sigma for w, sc in scores.items()}
    warnings = [*session.warnings, *_coverage_warnings(cov95_braking),
                *_beyond_training(s2, session.dt, fit)]
    return {
        "session": str(session.path),
        "samples": len(session.frame),
        "rate_hz": session.rate_hz,
        "residual_rmse_mm": res,
        "improvement_pct": improvement,
        "pressure_rmse_mpa": p_rmse,
        "coverage_95": cov95,
        "coverage_95_braking": cov95_braking,
        "consistency": {w: t.consistency for w, t in tracks.items()},
        "noise_scale": {w: t.noise_scale for w, t in tracks.items()},
        "outside_1sigma": out1,
        "noise_choice": _noise_choice(fit),
        "smoothed": smooth,
        "pv_fit": {
            "curve": fit.pv_curve + (
                f", chosen on held-out blocks of the training session ({_pv_choice(fit)})"
                if fit.pv_heldout_mpa else ""),
            "knots_mm": list(fit.pv_knots_mm),
            "knot_pressures_mpa": list(fit.pv_knot_mpa),
            "heldout_rmse_mpa": dict(zip(candidate_names() if fit.pv_heldout_mpa else (),
                                         fit.pv_heldout_mpa, strict=True)),
            "coefficients_mpa": list(fit.pv_coeffs),
            "coefficients_used": not fit.pv_knots_mm,
            "powers": list(PV_POWERS),
            "stroke_mm": fit.stroke_mm,
            "training_session": fit.train_session,
            "rmse_mpa": fit.pv_rmse_mpa,
            "s2_max_mm": fit.s2_max_mm if np.isfinite(fit.s2_max_mm) else None,
            "beyond": "the curve's tangent beyond s2_max_mm (null: the polynomial everywhere)"
                      if not fit.pv_knots_mm else "the last segment's slope beyond the last knot",
        },
        "disk_fit": {
            "three_slope": list(fit.disk),
            "omega_n_rad_s": fit.omega_n,
            "damping": fit.damping,
            "tau_z_s": fit.tau_z,
            "rmse_mm": fit.disk_rmse_mm,
            "pedal_scale_n": fit.pedal_scale_n,
            "pedal_dof": spec.pedal_dof,
        },
        "bench": spec.id,
        "warnings": warnings,
        "seconds": {"train": t_train, **{w: tracks[w].seconds for w in OBSERVERS}},
        "n_repairs": {w: tracks[w].filt.n_repairs for w in OBSERVERS},
    }


@dataclass(frozen=True)
class _PressureScores:
    """One observer's pressures against the session's sensors.

    Attributes
    ----------
    rmse_mpa : dict of str to float or None — MPa
        RMSE of each pressure state (None: no sensor, or no finite sample).
    outside_1sigma : dict of str to float or None
        Share of the samples more than 1σ off the sensor.
    coverage_95 : float or None
        Share of all scored samples inside the 95 % band.
    coverage_95_braking : float or None
        The same while the brake is applied; None below :data:`MIN_APPLIED` samples.
    """

    rmse_mpa: dict[str, float | None]
    outside_1sigma: dict[str, float | None]
    coverage_95: float | None
    coverage_95_braking: float | None


def _pressure_scores(tr: ObserverTrack, validation: dict[str, Array]) -> _PressureScores:
    """Score an observer's track ``tr`` on the pressure sensors of ``validation`` (MPa)."""
    p_rmse: dict[str, float | None] = {}
    out1: dict[str, float | None] = {}
    inside, total, inside_b, total_b = 0, 0, 0, 0
    for i, state in enumerate(("p_m", "p_f", "p_r")):
        if state not in validation:
            p_rmse[state] = None
            out1[state] = None
            continue
        err = tr.x[:, i] - validation[state]
        ok = np.isfinite(err)
        p_rmse[state] = _rmse(err)
        out1[state] = float(np.mean(np.abs(err[ok]) > np.maximum(tr.std[ok, i], 1e-12)))
        hit, applied = in_band(validation[state], tr.x[:, i], tr.std[:, i], APPLIED_MPA)
        inside += int(hit.sum())
        total += hit.size
        inside_b += int(hit[applied].sum())
        total_b += int(applied.sum())
    return _PressureScores(
        rmse_mpa=p_rmse,
        outside_1sigma=out1,
        coverage_95=inside / total if total else None,
        coverage_95_braking=inside_b / total_b if total_b >= MIN_APPLIED else None,
    )


def _coverage_warnings(cov95_braking: dict[str, float | None]) -> list[str]:
    """The warning when an observer's 95 % band covers too little of the applied samples."""
    low = {w: c for w, c in cov95_braking.items() if c is not None and c < LOW_COVERAGE}
    if not low:
        return []
    return [
        "scored against this session's own pressure sensor, the 95 % band covers "
        + ", ".join(f"{100 * c:.0f} % ({w.upper()})" for w, c in low.items())
        + f" while the brake is applied (above {APPLIED_MPA:g} MPa): the booster does"
        " not follow the training result's relation here beyond what the band admits —"
        " its p–V curve shifted or scaled since (seals, fluid), or the pressure sensor or"
        " its unit is off; `diagnose --rig ebooster` on this session names and sizes a"
        " shift, `--with-effect auto` carries it, or retrain on a session of the day"]


# The noise_scale (mean NIS per reading) above which a session is taken to depart from its
# training result beyond noise. On the independent benches (vehicle, open-loop, production
# sessions, a p-V shifted and not carried, a pressure sensor in the wrong unit) it is 1.0:
# the model's own errors stay inside its noise; a reversed reaction_disk_delta makes it 5.5.
# At 3 the innovations spread sqrt(3) = 1.7x wider than the noise admits, far beyond what
# the benches leave, well below what a wrong input gives.
NOISE_SCALE_WARN = 3.0


def _beyond_noise(tracks: dict[str, ObserverTrack], lost: dict[str, str], path: Path,
                  train_session: str) -> str:
    """The warning when an observer's innovations are far larger than its noise admits
    (noise_scale above :data:`NOISE_SCALE_WARN`); '' otherwise. An observer that lost its
    track has its own warning."""
    scales = {w: t.noise_scale for w, t in tracks.items() if w not in lost}
    if not scales or max(scales.values()) <= NOISE_SCALE_WARN:
        return ""
    figures = ", ".join(f"{s:.1f} ({w.upper()})" for w, s in scales.items())
    return (
        f"{path.name}: the observers' δ innovations are {figures} times the variance their"
        f" noise admits (mean NIS per reading; about 1.0 on a session that follows the"
        f" training result, warned above {NOISE_SCALE_WARN:g}): this session departs from"
        f" the training ({Path(train_session).name}) beyond noise. Likely causes:"
        f" {DELTA} or {S2} with a reversed sign or in the wrong unit, another booster than"
        " the one trained, or a p–V characteristic moved since. The bands were widened by"
        " sqrt(noise_scale) ("
        + ", ".join(f"{np.sqrt(s):.2f}x" for s in scales.values())
        + ") to hold the innovations; the estimates were not corrected: check the two"
        " channels' sign and unit, or retrain on a session of this booster")


def _beyond_training(s2: Array, dt: float, fit: BoosterFit) -> list[str]:
    """The warning when the screw travels past the training data's furthest travel (by
    more than 2 %): there the pressures follow the p-V curve's tangent, not a fit."""
    beyond = s2 > 1.02 * fit.s2_max_mm
    if not beyond.any():
        return []
    return [f"the screw travels to {float(np.max(s2)):.2f} mm, beyond the training"
            f" session's {fit.s2_max_mm:.2f} mm for {beyond.sum() * dt:.1f} s: there the"
            f" p-V curve is continued along its tangent from {fit.pressure(fit.s2_max_mm):.1f}"
            " MPa, not fitted, and the pressures are extrapolated; train on a session that"
            " reaches these pressures"]


def _noise_choice(fit: BoosterFit) -> dict[str, Any]:
    """``noise_choice`` of summary.json: the process-noise factor and its evidence."""
    if not fit.q_heldout_nats:
        why = ("the datasheet's process noise: no training session to choose it on (a fit"
               " file without a choice, or a training session too short to cut in two)")
    else:
        best = Q_FACTORS[int(np.nanargmax(fit.q_heldout_nats))]
        if fit.q_factor != 1.0:
            kept = f"{fit.q_factor:g}x used"
        elif best < 1.0:
            kept = ("the datasheet's kept: never less, since a slow training sweep holds"
                    " none of the fast applies where the model errs")
        else:
            kept = f"the datasheet's kept (another must gain {Q_MARGIN_NATS:g} nats per reading)"
        why = (f"trained on one half of {Path(fit.train_session).name}, observed on the other"
               f" (both ways): the held-out log-likelihood of its pressure sensor is highest"
               f" at {best:g}x the datasheet's process noise; {kept}"
               + ("; that is the largest factor tried: the training session's held-out"
                  " pressures would take more still, while a session's own innovations"
                  " (consistency) say whether its band is too wide or too narrow"
                  if best == Q_FACTORS[-1] else ""))
    return {"q_factor": fit.q_factor, "factors": list(Q_FACTORS) if fit.q_heldout_nats else [],
            "heldout_loglik_per_reading": list(fit.q_heldout_nats), "why": why}


def frame_columns(result: EboosterResult) -> tuple[dict[str, Array], dict[str, str]]:
    """The ebooster.parquet columns (OUTPUTS.md) and their units."""
    cols: dict[str, Array] = {"time": result.time}
    units = {"time": "s"}
    unit_of = {"p_m": "MPa", "p_f": "MPa", "p_r": "MPa", "zeta1": "mm", "zeta2": "mm/s"}
    for w in OBSERVERS:
        tr = result.tracks[w]
        for i, name in enumerate(STATE_NAMES):
            cols[f"{w}_{name}"] = tr.x[:, i]
            cols[f"{w}_{name}_std"] = tr.std[:, i]
            units[f"{w}_{name}"] = units[f"{w}_{name}_std"] = unit_of[name]
        cols[f"{w}_residual"] = tr.residual
        units[f"{w}_residual"] = "mm"
    return cols, units


