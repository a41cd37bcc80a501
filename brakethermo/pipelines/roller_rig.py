"""Rolling radius of a tram wheel on the roller rig by a joint UKF (Onat, Voltr, Lata).

``run_roller_rig(path, options)`` reads a session, runs the joint UKF of the paper on
the state [omega_w, omega_r, r_w] once per starting guess (all guesses in one call),
smooths each run with the unscented RTS smoother (on by default offline), and scores
the tracks against the session's radius reference when it has one.
``write_roller_rig(result, out)`` writes ``roller_rig.parquet``, ``summary.json`` and
the report page (OUTPUTS.md, "roller-rig").
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from brakethermo.errors import ConfigError, DataError
from brakethermo.estimation import UnscentedKalmanFilter, urts_smooth
from brakethermo.estimation.consistency import nis_consistency, variance_scale
from brakethermo.io.load import load_session
from brakethermo.io.session import Session
from brakethermo.models.roller_rig import CREEP_LAWS, CreepEffects, RollerRigModel
from brakethermo.numeric import rmse
from brakethermo.pipelines.rig_carry import creep_effects
from brakethermo.pipelines.rig_checks import Expect, check_rig_channels
from brakethermo.pipelines.tuning import ROLLER_RIG_TUNINGS as TUNINGS
from brakethermo.results.roller_rig import GuessRun, RollerRigResult
from brakethermo.rigs.motor import motor_torque
from brakethermo.rigs.roller_rig import FilterDefaults, RollerRigSpec, load_roller_rig

PIPELINE = "roller_rig"
CHANNELS = (
    "wheel_omega", "roller_omega", "wheel_torque", "normal_force", "roller_torque",
    "rolling_radius_ref",
)  # fmt: skip
FREE_FRACTION = 0.02  # |request| below this share of its peak: free rolling
TRACTION_FRACTION = 0.5  # |request| above this share of its peak: traction
MIN_TRACTION_NM = 20.0  # a session whose request never exceeds this has no traction
CONVERGED_MM = 1.0  # the estimate has converged once it stays this close to its end value
CONVERGENCE_WINDOW_S = 0.25  # moving average of the filter track judged for convergence
SUPPLY_FACT = "roller_supply_hz"
SUPPLY_FACTS = (SUPPLY_FACT, "supply_hz")  # session facts naming the roller's supply, Hz
ROLLER_RADIUS_FACTS = ("roller_radius_m",)  # ... and a roller radius unlike the datasheet's
ROLLER_RADIUS_RANGE_M = (0.1, 2.5)


def session_spec(session: Session, spec: RollerRigSpec) -> tuple[RollerRigSpec, str]:
    """The datasheet with the session's own roller radius where it states one (a
    re-profiled roller: the speed ratio's radius moves with it), and where the roller
    radius came from."""
    for key in ROLLER_RADIUS_FACTS:
        fact = session.metadata.get(key)
        if fact is None:
            continue
        try:
            value = float(fact)
        except ValueError:
            value = math.nan
        lo, hi = ROLLER_RADIUS_RANGE_M
        if not lo <= value <= hi:
            raise DataError(f"session fact {key}={fact!r} is not a roller radius in metres"
                            f" ({lo:g}-{hi:g}); fix it, or leave it out for the datasheet's"
                            f" {spec.roller_radius:g} m", path=session.path)
        said = ("as" if value == spec.roller_radius else "the datasheet")
        return replace(spec, roller_radius=value), (
            f"session fact {key} ({said} {spec.id} says {spec.roller_radius:g} m)")
    return spec, f"datasheet {spec.id}"


DATASHEET_FACT = "rig_datasheet"  # the session's rig datasheet id (the simulator writes it)


def datasheet_warning(session: Session, spec: RollerRigSpec, roller_source: str) -> list[str]:
    """A warning when the session names another rig datasheet than the one read.

    A session simulated on ``roller-rig-mod`` (roller radius 0.46 m) and read with the
    shipped datasheet (0.4525 m) gave 342.55 mm against its reference 348.20 mm, and no
    word: the fact was ignored.

    Parameters
    ----------
    session : Session
    spec : RollerRigSpec
        The datasheet read (``--rig``), with the session's own roller radius if it
        states one.
    roller_source : str
        Where the roller radius came from (:func:`session_spec`).

    Returns
    -------
    list of str
        One sentence naming both datasheets and ``--rig``, or nothing.
    """
    named = session.metadata.get(DATASHEET_FACT)
    if named is None or str(named).strip() in ("", spec.id):
        return []
    radius = (f"the roller radius {spec.roller_radius:g} m is the session's own"
              if roller_source.startswith("session fact") else
              f"its roller radius {spec.roller_radius:g} m, which the session does not state,"
              " turns the speed ratio into the wheel radius")
    return [f"the session names the rig datasheet {named!r} (fact {DATASHEET_FACT}); this run"
            f" read {spec.id!r} (--rig): {radius}, and its inertias, motor and contact are"
            f" {spec.id!r}'s, not {named!r}'s; give --rig with the TOML file of {named!r}"]


REF_EXPECT = Expect("rolling_radius_ref", "m", 2.0, positive=True, role="score")

RADIUS_RANGE_MM = (100.0, 1000.0)  # a tram wheel's rolling radius, and the accepted guesses
RATIO_TOLERANCE = 0.03  # traction creep moves the speed-ratio radius by well under this
RATIO_SIGMAS = 2.0  # a free-rolling departure from the ratio beyond this many sigmas is said


@dataclass(frozen=True)
class RollerRigOptions:
    """How to run the estimator.

    Attributes
    ----------
    r0_mm : tuple of float — starting guesses of the radius, mm (one filter each).
    smoother : bool — unscented RTS smoother (offline default); False: the paper's
        filter-only run.
    rig : str — datasheet id or TOML path.
    supply_hz : float or None — roller-motor supply frequency, Hz; default the session
        fact ``roller_supply_hz``, else inferred from free rolling.
    aliases : Path or None — channel alias TOML.
    tuning : {"measured", "paper"} — R from the session's speed noise and the
        datasheet's ``q_measured``; or the paper's P0/Q/R exactly (eq. 15a-15c).
    creep_law : {"polach", "fastsim"} — the estimator's creep force: Polach's law, or
        Kalker's FASTSIM (20 x 20) with Polach's friction.
    with_effect : str — the creep curve's departures carried from a diagnosis: 'none',
        'auto', a diagnosis.json or NAME=VALUE pairs
        (:mod:`brakethermo.pipelines.rig_carry`).
    """

    r0_mm: tuple[float, ...] = (320.0, 400.0)
    smoother: bool = True
    rig: str = "roller-rig"
    supply_hz: float | None = None
    aliases: Path | None = None
    tuning: str = "measured"
    creep_law: str = "polach"
    with_effect: str = "none"

    def validated(self) -> RollerRigOptions:
        """Self after checks (ConfigError naming the option)."""
        if self.creep_law not in CREEP_LAWS:
            raise ConfigError(
                f"--creep must be one of {', '.join(CREEP_LAWS)}, got {self.creep_law!r}"
            )
        if self.tuning not in TUNINGS:
            raise ConfigError(f"--tuning must be one of {', '.join(TUNINGS)}, got {self.tuning!r}")
        if not self.r0_mm:
            raise ConfigError("give at least one starting guess --r0 MM")
        for r in self.r0_mm:
            lo, hi = RADIUS_RANGE_MM
            if not (math.isfinite(r) and lo <= r <= hi):
                raise ConfigError(f"--r0 {r:g} mm is not a plausible wheel radius"
                                  f" ({lo:g}-{hi:g} mm)")
        labels = [guess_label(r) for r in self.r0_mm]
        if len(set(labels)) != len(labels):
            raise ConfigError(f"starting guesses repeat: {', '.join(labels)} mm")
        if self.supply_hz is not None and not (
            math.isfinite(self.supply_hz) and 0.5 <= self.supply_hz <= 200.0
        ):
            raise ConfigError(f"--supply-hz {self.supply_hz:g} is out of range (0.5-200 Hz)")
        return self


def guess_label(r0_mm: float) -> str:
    """Column suffix of a guess: its value in mm (``320``, ``347.5``)."""
    return f"{r0_mm:g}"


def _finite_series(session: Session, name: str) -> np.ndarray:
    v = session.values(name)
    ok = np.isfinite(v)
    if not ok.any():
        raise DataError("has no finite sample; check the logger", path=session.path, channel=name)
    return v


def _fill(v: np.ndarray) -> np.ndarray:
    """Interpolate NaN inputs between samples, hold them at the ends."""
    ok = np.isfinite(v)
    if ok.all():
        return v
    idx = np.arange(v.size)
    return np.interp(idx, idx[ok], v[ok])


def _check_speed(session: Session, name: str, v: np.ndarray) -> None:
    if np.nanmax(np.abs(v)) < 1e-6:
        raise DataError(
            "is zero throughout: the encoder or its scaling is not working; check the"
            " channel and its unit", path=session.path, channel=name,
        )  # fmt: skip
    if np.nanmin(v) < -1e-3 and np.nanmax(v) > 1e-3:
        raise DataError(
            "changes sign: the rig must roll one way through the session; split the file",
            path=session.path, channel=name,
        )  # fmt: skip


def speed_noise_var(omega: np.ndarray, mask: np.ndarray) -> float:
    """Variance of a speed channel's sample noise, (rad/s)^2, from free rolling.

    Half the variance of successive differences (white noise doubles in a difference;
    the slow speed changes of free rolling do not count), the extreme 0.5 % on each side
    trimmed so that steps and gap edges do not inflate it; floored at 1e-10.
    """
    d = np.diff(omega)
    d = d[mask[1:] & mask[:-1] & np.isfinite(d)]
    if d.size < 10:
        return 1e-5
    lo, hi = np.percentile(d, [0.5, 99.5])
    d = d[(d >= lo) & (d <= hi)]
    return max(0.5 * float(np.var(d)), 1e-10)


def infer_supply_hz(
    spec: RollerRigSpec, omega_w: np.ndarray, omega_r: np.ndarray, free: np.ndarray
) -> float:
    """Roller-motor supply frequency from free rolling, Hz.

    In free rolling the motor only covers the bearing losses of both shafts (the wheel's
    through the contact, F r_w = T_bw): solve T_A(omega_r, f) = T_br + T_bw R_r / r_w for f.
    """
    w_r = float(np.nanmedian(omega_r[free]))
    w_w = float(np.nanmedian(omega_w[free]))
    b = spec.bearings
    need = (
        b.roller_coulomb
        + b.roller_viscous * w_r
        + (b.wheel_coulomb + b.wheel_viscous * w_w) * spec.roller_radius / spec.nominal_radius
    )
    f_rot = w_r * spec.motor.pole_pairs / (2.0 * math.pi)  # zero slip
    return float(
        brentq(
            lambda f: float(motor_torque(spec.motor, w_r, f)) - need,
            f_rot,
            f_rot * 1.5 + 1e-3,
            xtol=1e-10,
        )
    )


def windowed_mean(x: np.ndarray, dt: float) -> np.ndarray:
    """Trailing mean over CONVERGENCE_WINDOW_S (NaN until the first window is full)."""
    w = max(1, round(CONVERGENCE_WINDOW_S / dt))
    return pd.Series(x).rolling(w, min_periods=w).mean().to_numpy()


def convergence_time(
    t: np.ndarray, track_mm: np.ndarray, target_mm: float, dt: float
) -> float | None:
    """Time from which every 0.25 s average of the track is within 1 mm of ``target_mm``.

    ``None`` when the track ends outside. Judged on the forward filter (the online
    estimate) against its own end value, or against the truth in the tests.
    """
    w = max(1, round(CONVERGENCE_WINDOW_S / dt))
    avg = windowed_mean(track_mm, dt)
    out = ~(np.abs(avg - target_mm) <= CONVERGED_MM)
    if out[-1]:
        return None
    last = np.flatnonzero(out[w - 1 :])
    start = 0 if last.size == 0 else int(last[-1]) + 1  # first good window, by its start
    return float(t[start] - t[0])


def rolling_sign(roller_omega: np.ndarray) -> float:
    """+1 or -1: the sign that makes the roller roll forward, as the model does (applied
    to the speeds, the wheel torque and the roller's)."""
    return 1.0 if np.nanmedian(roller_omega) > 0 else -1.0


def rig_inputs(session: Session, spec: RollerRigSpec) -> tuple[Any, ...]:
    """The session's speeds (rolling forward), torque and load, checked against physics, and
    the free-rolling, traction and both-speeds masks."""
    session.require("wheel_omega", "roller_omega", "wheel_torque")
    w_w = _finite_series(session, "wheel_omega")
    w_r = _finite_series(session, "roller_omega")
    _check_speed(session, "wheel_omega", w_w)
    _check_speed(session, "roller_omega", w_r)
    sign = rolling_sign(w_r)
    w_w, w_r = sign * w_w, sign * w_r
    torque = _fill(_finite_series(session, "wheel_torque")) * sign
    peak = float(np.max(np.abs(torque)))
    if peak < MIN_TRACTION_NM:
        raise DataError(
            f"never exceeds {MIN_TRACTION_NM:g} N m (peak {peak:.1f} N m): no traction at all,"
            " so creep cannot reveal the radius; use a session with traction phases",
            path=session.path, channel="wheel_torque",
        )  # fmt: skip
    # the rig's own checks above name the common faults first; then every channel
    notes = check_rig_channels(session, (
        Expect("wheel_omega", "rad/s", 1e3), Expect("roller_omega", "rad/s", 1e3),
        Expect("normal_force", "N", 5e5, setpoint=True),
        Expect("wheel_torque", "N m", 1e5, measured=False),
        Expect("roller_torque", "N m", 1e5, role="score"),
        REF_EXPECT))
    warnings = [*session.warnings, *notes]
    if session.has("normal_force"):
        normal = _fill(_finite_series(session, "normal_force"))
        if np.nanmin(normal) <= 0:
            raise DataError(
                "holds non-positive loads; check its unit and zero",
                path=session.path,
                channel="normal_force",
            )
    else:
        normal = np.full(w_w.size, spec.nominal_load)
        warnings.append(
            f"no normal_force channel: the datasheet load {spec.nominal_load:g} N is used"
        )
    free = np.abs(torque) <= FREE_FRACTION * peak
    traction = np.abs(torque) >= TRACTION_FRACTION * peak
    both = np.isfinite(w_w) & np.isfinite(w_r)
    if not (free & both).any():
        raise DataError(
            "no free-rolling sample (wheel_torque near zero) with both speeds",
            path=session.path,
            channel="wheel_torque",
        )

    return w_w, w_r, torque, normal, warnings, free, traction, both


def _noise(opts: RollerRigOptions, fd: FilterDefaults, w_w: np.ndarray, w_r: np.ndarray,
           free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The filter's process and measurement noise variances (diagonals): the paper's, or
    the datasheet's measured Q and R from the speeds' noise in free rolling, (rad/s)²."""
    if opts.tuning == "paper":
        return np.array(fd.q), np.array(fd.r)
    Q = np.array(fd.q_measured)
    R = np.array([speed_noise_var(w_w, free), speed_noise_var(w_r, free)])
    return Q, R


@dataclass(frozen=True)
class _Guesses:
    """The joint UKF run from every starting guess under a given creep model, with the
    session's inputs it needs; called with the model, it gives the guesses' runs checked
    against free rolling and their bands widened (:func:`creep_model_band`,
    :func:`ratio_band`)."""

    opts: RollerRigOptions
    fd: FilterDefaults
    t: np.ndarray  # s, session time
    dt: float  # s
    y: np.ndarray  # (K, 2) wheel and roller speeds, rad/s, rolling forward
    start: tuple[float, float]  # rad/s, both speeds at the first step that has both
    torque: np.ndarray  # N m, wheel torque
    normal: np.ndarray  # N, normal force
    supply: float  # Hz, roller-motor supply frequency
    Q: np.ndarray  # process-noise variances (diagonal)
    R: np.ndarray  # (rad/s)², speed noise variances (diagonal)
    ratio_mm: float  # mm, the free-rolling speed-ratio radius
    free: np.ndarray  # (K,) bool, free rolling with both speeds

    def __call__(self, model: RollerRigModel) -> list[GuessRun]:
        opts, fd, t, dt = self.opts, self.fd, self.t, self.dt
        H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        f = model.transition(dt, self.torque, self.normal, np.full(t.size, self.supply))
        ukf = UnscentedKalmanFilter(
            f, np.diag(self.Q), np.diag(self.R), H=H, alpha=fd.alpha, beta=fd.beta,
            kappa=fd.kappa,
        )  # fmt: skip

        def one_guess(r0: float) -> GuessRun:
            x0 = np.array([self.start[0], self.start[1], r0 * 1e-3])
            res = ukf.run(x0, np.diag(fd.p0), self.y,
                          store="smoother" if opts.smoother else "diag")
            return _guess_run(r0, res, opts.smoother, t, dt)

        # The guesses are independent and the compiled model and filter steps release the
        # GIL: one thread per guess, at most one per core.
        workers = max(1, min(len(opts.r0_mm), os.cpu_count() or 1))
        with ThreadPoolExecutor(max_workers=workers) as pool:
            runs = list(pool.map(one_guess, opts.r0_mm))
        checked = [creep_model_band(_checked_guess(run, self.ratio_mm, one_guess), self.torque,
                                    self.free) for run in runs]
        return [ratio_band(run, self.ratio_mm, _settled(run, self.free, t)) for run in checked]


def run_roller_rig(path: str | Path, options: RollerRigOptions | None = None) -> RollerRigResult:
    """Estimate the rolling radius of the session's wheel from every starting guess.

    Parameters
    ----------
    path : str or Path — session file (.mcap, .parquet, .csv) with the channels of
        CHANNELS.md "Roller rig".
    options : RollerRigOptions, optional

    Returns
    -------
    RollerRigResult

    Raises
    ------
    DataError
        Missing channel, a speed channel that is all zero, no traction at all, an
        unknown unit (from the reader).
    ConfigError
        Bad options or datasheet.
    """
    opts = (options or RollerRigOptions()).validated()
    spec = load_roller_rig(opts.rig)
    t_start = time.perf_counter()
    session = load_session(path, rate_hz=None, channels=CHANNELS, aliases=opts.aliases)
    spec, roller_source = session_spec(session, spec)
    w_w, w_r, torque, normal, warnings, free, traction, both = rig_inputs(session, spec)
    supply, source = _supply(session, opts, spec, w_w, w_r, free & both)
    dt = session.dt
    t = session.time
    effects, carried = creep_effects(opts.with_effect, session, rig=opts.rig,
                                     creep_law=opts.creep_law, aliases=opts.aliases)
    Q, R = _noise(opts, spec.filter, w_w, w_r, free & both)
    first = int(np.flatnonzero(both)[0])
    ratio_mm = free_rolling_radius_mm(session, spec, w_w, w_r, free & both)
    guesses = _Guesses(opts, spec.filter, t, dt, np.column_stack([w_w, w_r]),
                       (w_w[first], w_r[first]), torque, normal, supply, Q, R, ratio_mm,
                       free & both)
    model = RollerRigModel.from_spec(spec, creep_law=opts.creep_law)
    suspects = options_suspected(opts, session)
    try:
        runs = guesses(model)
    except DataError as exc:  # the filter's verdict on the session: name the file
        raise DataError(exc.detail + suspects, path=session.path) from None
    if effects != CreepEffects():
        model, runs = _judged(model, runs, replace(model, effects=effects), guesses, carried,
                              free & both, traction & both)
    warnings = [*warnings, *dict.fromkeys(
        w for run in runs
        if (w := ratio_warning(run, ratio_mm, _settled(run, free & both, t))) is not None),
        *_implausible(runs, suspects)]
    s_x, F = model.creep(runs[0].states[:, 0], runs[0].states[:, 1], runs[0].states[:, 2], normal)
    warnings += force_warning(F, torque, runs[0].states[:, 2], traction & both, suspects)
    naive = w_r * spec.roller_radius / np.where(np.abs(w_w) > 1e-9, w_w, np.nan) * 1e3
    ref = session.constant("rolling_radius_ref")
    # a reference the checks found implausible (said in the warnings) scores nothing
    ref_mm = ref * 1e3 if ref is not None and 0.0 < ref <= REF_EXPECT.most else None
    warnings += [*datasheet_warning(session, spec, roller_source),
                 *reference_warning(runs[0], ref_mm, spec)]
    elapsed = time.perf_counter() - t_start
    result = RollerRigResult(
        stem=session.path.stem, session=session, spec=spec, options=opts, time=t,
        omega_w=w_w, omega_r=w_r, torque=torque, normal_force=normal, creep_force=F,
        creepage=s_x, naive_mm=naive, free=free, traction=traction, runs=tuple(runs),
        supply_hz=supply, supply_source=source, reference_mm=ref_mm, summary={},
    )  # fmt: skip
    result.summary.update(_summary(result, warnings, elapsed))
    result.summary["filter"].update(
        {
            "tuning": opts.tuning,
            "creep_law": opts.creep_law,
            "with_effect": carried,
            "roller_radius_m": spec.roller_radius,
            "roller_radius_source": roller_source,
            "q_used": Q.tolist(),
            "r_used": R.tolist(),
        }
    )
    return result


MAX_MEAN_NIS = 20.0  # clean sessions give 1-5; a reversed torque sign gave 80
# creep force / (wheel torque / radius) in steady traction that a rig can show, the
# filter's here and the roller transducer's in diagnose: our own rig at 15-30 km/h
# 0.72-1.24, an independent rig's stiffer roller motor 2.1-3.6
FORCE_RATIO_RANGE = (0.5, 2.0)


def options_suspected(opts: RollerRigOptions, session: Session) -> str:
    """The options given that change the model, as a clause a message about a model that
    does not fit the session ends with ('' when none): a ``--supply-hz`` the session's
    fact contradicts (or no fact confirms), a ``--tuning`` or ``--creep`` not the default.
    A user's option is the first thing to suspect: the session was fine without it."""
    said = []
    if opts.supply_hz is not None:
        key = next((k for k in SUPPLY_FACTS if k in session.metadata), None)
        try:
            fact = float(session.metadata[key]) if key else None
        except ValueError:  # _supply refuses such a fact unless the option overrides it
            fact = None
        if fact is None:
            said.append(f"--supply-hz {opts.supply_hz:g} (no session fact confirms it;"
                        " without it the supply is inferred from free rolling)")
        elif not math.isclose(fact, opts.supply_hz, rel_tol=1e-6):
            said.append(f"--supply-hz {opts.supply_hz:g}, where the session's fact {key}"
                        f" says {fact:g} Hz")
    default = RollerRigOptions()
    if opts.tuning != default.tuning:
        said.append(f"--tuning {opts.tuning} (the paper's P0, Q and R, not this session's"
                    " measured noise)")
    if opts.creep_law != default.creep_law:
        said.append(f"--creep {opts.creep_law} (the default is {default.creep_law})")
    if not said:
        return ""
    return ("; a likely cause is an option given, which changes the model: "
            + "; ".join(said) + " — run without it to compare")


def force_warning(force: np.ndarray, torque: np.ndarray, radius_m: np.ndarray,
                  traction: np.ndarray, suspects: str = "") -> list[str]:
    """A warning when, under traction, the creep force the filter infers (N) is not what
    the wheel's torque (N m) can pass through the contact at its radius (m): the wheel's
    own balance F r = T holds to its bearing loss and inertia (a few per cent), so a
    factor means the model's other side — the roller motor's torque from the datasheet
    and the supply, the creep law — is not this rig's (an independent rig's stiffer
    motor: 4320 N inferred against 1560 N possible), or the torque's sign is reversed."""
    pull = torque / radius_m
    ok = traction & np.isfinite(force) & np.isfinite(pull) & (np.abs(pull) > 0)
    if ok.sum() < 10:
        return []
    ratio = float(np.median(force[ok] / pull[ok]))
    lo, hi = FORCE_RATIO_RANGE
    if lo <= ratio <= hi:
        return []
    why = ("the opposite sign: check wheel_torque's sign (traction +, CHANNELS.md)"
           if ratio < 0 else
           "so the model's roller side (the roller motor's torque at this supply, from the"
           " rig datasheet and --supply-hz) or its creep law is not this rig's, or"
           " wheel_torque's sign or unit is off (traction +, CHANNELS.md)")
    return [f"IMPLAUSIBLE RESULT: under traction the filter's creep force is {ratio:.2f}x"
            f" what the wheel's torque can pass through the contact (T/r, median), {why};"
            " the radius under traction follows that model (the free-rolling radius and"
            " the speed ratio do not)" + suspects]


def _implausible(runs: Sequence[GuessRun], suspects: str = "") -> list[str]:
    """A warning when the filter's innovations are far beyond its noise on every guess:
    no setting of the noise makes such a model describe the session."""
    nis = min(float(r.consistency["mean_nis"]) for r in runs)
    if not nis > MAX_MEAN_NIS:
        return []
    return [f"IMPLAUSIBLE RESULT: the filter's innovations are {nis:.0f}x its noise (mean NIS)"
            " on every guess, the band widened to match: the model does not describe this"
            " session — check wheel_torque's sign (traction +, CHANNELS.md) and the units of"
            " the speeds, the torque and normal_force; with those right, the roller's drive"
            " is not the datasheet's (a speed controller on the roller, another motor)"
            + suspects]


def _guess_run(r0: float, res: Any, smoother: bool, t: np.ndarray, dt: float) -> GuessRun:
    """One guess's tracks from its filter run (and the smoother), its spread widened by
    the mean NIS where the innovations show the filter over-confident."""
    consistency = nis_consistency(res.nis, res.n_obs, res.innovation)
    scale = variance_scale(consistency)
    filt_mm = res.x_filt[:, 2] * 1e3
    filt_std = np.sqrt(res.var_filt[:, 2] * scale) * 1e3
    if smoother:
        sm = urts_smooth(res)
        states, var = sm.x_smooth, sm.var_smooth
    else:
        states, var = res.x_filt, res.var_filt
    return GuessRun(
        r0, states[:, 2] * 1e3, np.sqrt(var[:, 2] * scale) * 1e3, filt_mm, filt_std, states,
        convergence_time(t, filt_mm, float(filt_mm[-1]), dt),
        consistency=consistency, noise_scale=scale,
    )  # fmt: skip


def _judged(law: RollerRigModel, law_runs: list[GuessRun], changed: RollerRigModel,
            guesses: Any, carried: dict[str, Any], free: np.ndarray, traction: np.ndarray,
            ) -> tuple[RollerRigModel, list[GuessRun]]:
    """The datasheet's creep law or the carried one, as the session decides.

    The wheel's radius does not change with the torque: the law under which the first
    guess's radius moves less between free rolling and traction (:func:`traction_drift_mm`)
    is the one the speeds and torque support. The creep force a diagnosis fitted against a
    transducer can carry the transducer's own errors (bearing drag, inertia), so a carried
    curve is kept only where it makes the radius more constant. Records both drifts and the
    choice in ``carried`` (the summary's ``filter.with_effect``).
    """
    try:
        runs = guesses(changed)
    except DataError as exc:  # the filter does not converge with it: the datasheet's law
        carried.update({"kept": False, "note": f"not kept: with it {exc.detail}"})
        return law, law_runs
    before = traction_drift_mm(law_runs[0].radius_mm, free, traction)
    after = traction_drift_mm(runs[0].radius_mm, free, traction)
    kept = abs(after) < abs(before)
    carried.update({"kept": kept, "traction_drift_mm": {"datasheet": before, "carried": after}})
    if not kept:
        carried["note"] = (f"not kept: with it the radius moves {after:+.3f} mm from free"
                           f" rolling to traction, {before:+.3f} mm with the datasheet's law")
        return law, law_runs
    return changed, runs


def traction_drift_mm(radius_mm: np.ndarray, free: np.ndarray, traction: np.ndarray) -> float:
    """Mean radius under traction minus in free rolling, mm (0 for a right creep law)."""
    ok = np.isfinite(radius_mm)
    if not (free & ok).any() or not (traction & ok).any():
        return 0.0
    return float(np.mean(radius_mm[traction & ok]) - np.mean(radius_mm[free & ok]))


def free_rolling_radius_mm(session: Session, spec: RollerRigSpec, w_w: np.ndarray,
                           w_r: np.ndarray, free: np.ndarray) -> float:
    """The wheel radius the free-rolling speed ratio gives, mm (DataError if no tram wheel
    has it): sum(omega_r) R_r / sum(omega_w) over the free-rolling samples."""
    ratio_mm = float(np.sum(w_r[free]) * spec.roller_radius / np.sum(w_w[free]) * 1e3)
    if not (math.isfinite(ratio_mm) and RADIUS_RANGE_MM[0] <= ratio_mm <= RADIUS_RANGE_MM[1]):
        raise DataError(
            f"the free-rolling speed ratio gives a wheel radius of {ratio_mm:.1f} mm, which no"
            " tram wheel has: check the units of wheel_omega and roller_omega (rad/s) and the"
            " roller radius of the rig datasheet", path=session.path, channel="wheel_omega")
    return ratio_mm


def _checked_guess(run: GuessRun, ratio_mm: float, rerun: Any) -> GuessRun:
    """A guess whose filter ended where free rolling says no wheel is, re-started.

    The joint UKF is locally convergent: from a guess far outside its basin it can settle
    on a radius (even a negative one) that explains the speeds with an absurd creep. The
    free-rolling speed ratio bounds the answer (traction creep moves it by well under
    :data:`RATIO_TOLERANCE`); a final radius outside that is re-run from the ratio, and
    the summary says so.
    """
    final = float(run.filter_mm[-1])
    if math.isfinite(final) and abs(final - ratio_mm) <= RATIO_TOLERANCE * ratio_mm:
        return run
    again = rerun(ratio_mm)
    end = float(again.filter_mm[-1])
    if not (math.isfinite(end) and abs(end - ratio_mm) <= RATIO_TOLERANCE * ratio_mm):
        raise DataError(
            f"the rolling-radius filter does not converge near the free-rolling ratio radius"
            f" {ratio_mm:.1f} mm (from --r0 {run.r0_mm:g} mm it ended at {final:.1f} mm, from"
            f" the ratio at {end:.1f} mm): the speeds and the torque do not fit one radius;"
            " check the units of wheel_omega, roller_omega, wheel_torque and normal_force,"
            " and the rig datasheet")
    return replace(again, r0_mm=run.r0_mm, restart=(
        f"from {run.r0_mm:g} mm the filter ended at {final:.1f} mm, more than"
        f" {100 * RATIO_TOLERANCE:g} % from the free-rolling ratio radius {ratio_mm:.1f} mm"
        " (outside its basin of attraction); re-started from the ratio radius"))


def creep_model_band(run: GuessRun, torque: np.ndarray, free: np.ndarray) -> GuessRun:
    """The guess's bands widened by the creep law's error, as the session measures it.

    The wheel's radius does not change with the torque, so what the estimate does under
    traction that it does not do in free rolling is the creep law's error (another
    creep curve slope, friction): the estimate moves with the traction force while the
    filter's own variance, which trusts the model, stays put. Its size is measured on
    the session as a standard deviation proportional to the torque,
    ``sigma_m = c |T|`` with ``c^2 = sum(d^2 - s^2) / sum(T^2)`` over the samples off free
    rolling (``d``: departure from the free-rolling mean, ``s``: the filter's own
    standard deviation), and added to both bands in quadrature.
    """
    both = np.isfinite(run.radius_mm) & np.isfinite(torque)
    rolling = free & both
    loaded = ~free & both
    if not rolling.any() or not loaded.any():
        return replace(run, model_error_mm_per_knm=0.0)
    d = run.radius_mm[loaded] - float(np.mean(run.radius_mm[rolling]))
    tq = torque[loaded] * 1e-3  # kN m
    c2 = float(np.sum(d**2 - run.radius_std_mm[loaded] ** 2) / max(np.sum(tq**2), 1e-12))
    c = math.sqrt(max(c2, 0.0))
    model_var = (c * np.nan_to_num(torque) * 1e-3) ** 2
    return replace(
        run,
        radius_std_mm=np.sqrt(run.radius_std_mm**2 + model_var),
        filter_std_mm=np.sqrt(run.filter_std_mm**2 + model_var),
        model_error_mm_per_knm=c,
    )


def _settled(run: GuessRun, free: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The free-rolling samples after the guess's filter settled — its estimate within 1 mm
    of its end (else after the first quarter of the run) and its own spread down from the
    prior's (within 3x its free-rolling median): its start from a far guess is no model
    error."""
    start = (run.convergence_time_s if run.convergence_time_s is not None
             else 0.25 * (t[-1] - t[0]))
    out = free & (t - t[0] >= start) & np.isfinite(run.radius_std_mm)
    if out.any():
        out &= run.radius_std_mm <= 3.0 * float(np.median(run.radius_std_mm[out]))
    return out


def ratio_band(run: GuessRun, ratio_mm: float, free: np.ndarray) -> GuessRun:
    """The guess's bands widened by its departure from the free-rolling speed ratio.

    In free rolling the creep is nearly nil, so the speed ratio measures the radius
    directly (:func:`free_rolling_radius_mm`). A filter whose radius there departs from
    it more than its own spread allows runs on a model the session does not follow in
    free rolling — the roller motor's torque model at a low supply frequency, a supply
    frequency given wrong, drag the datasheet does not hold — and the same model then
    carries the traction phases. What the departure adds beyond the filter's own spread,
    ``e^2 = max(0, mean((r - r_ratio)^2 - s^2))`` over the free-rolling samples, is added
    to both bands in quadrature (0 where the filter agrees with the ratio). ``free``: the
    free-rolling samples after the filter settled (:func:`_settled`)."""
    ok = free & np.isfinite(run.radius_mm)
    if not ok.any():
        return run
    d = run.radius_mm[ok] - ratio_mm
    e2 = float(np.mean(d**2 - run.radius_std_mm[ok] ** 2))
    e = math.sqrt(max(e2, 0.0))
    return replace(run, radius_std_mm=np.sqrt(run.radius_std_mm**2 + e**2),
                   filter_std_mm=np.sqrt(run.filter_std_mm**2 + e**2),
                   ratio_offset_mm=float(np.mean(d)), ratio_error_mm=e)


REF_SIGMAS = 5.0  # an estimate this many of its 1σ from the session's reference is said ...
REF_FLOOR_MM = 0.5  # ... when also this far (a reference logged to 0.01 mm, measured)


def reference_warning(run: GuessRun, ref_mm: float | None, spec: RollerRigSpec) -> list[str]:
    """A warning when the final radius departs from the session's own reference
    (``rolling_radius_ref``) far beyond its band.

    The speed ratio, and with it the filter's radius, scales with the roller radius: a
    wrong roller radius or rig datasheet moves the estimate by the same factor while its
    band stays narrow (342.553 ± 0.071 mm against 348.20 mm, 80σ, with no word).

    Parameters
    ----------
    run : GuessRun
        The first guess's run (every guess ends at the same radius).
    ref_mm : float or None
        The session's reference radius, mm (None: none, or an implausible one).
    spec : RollerRigSpec
        The datasheet read, with the session's roller radius.

    Returns
    -------
    list of str
        One sentence with both radii, the departure in σ and the roller radius that
        would give the reference, or nothing.
    """
    if ref_mm is None:
        return []
    end, sd = float(run.radius_mm[-1]), float(run.radius_std_mm[-1])
    off = end - ref_mm
    if not (math.isfinite(off) and abs(off) > max(REF_SIGMAS * sd, REF_FLOOR_MM)):
        return []
    roller = spec.roller_radius * ref_mm / end  # the speed ratio's radius scales with it
    return [f"the estimate {end:.2f} ± {sd:.2f} mm departs from the session's reference"
            f" rolling_radius_ref {ref_mm:.2f} mm by {off:+.2f} mm"
            + (f" ({abs(off) / sd:.0f}x its 1σ)" if sd > 0.0 else "")
            + f": the speed ratio scales with the roller radius ({spec.roller_radius:g} m"
            f" here; {roller:.4f} m would give the reference) — check --rig (the rig"
            " datasheet) and the session's roller_radius_m, or the reference"]


def ratio_warning(run: GuessRun, ratio_mm: float, free: np.ndarray) -> str | None:
    """A sentence when the guess's free-rolling radius departs from the speed ratio by more
    than :data:`RATIO_SIGMAS` times the filter's own spread there, before its widening by
    the mean NIS (an over-confident filter is the same symptom); None otherwise."""
    ok = free & np.isfinite(run.radius_mm)
    if not ok.any() or run.ratio_error_mm == 0.0:
        return None
    own = math.sqrt(max(float(np.mean(run.radius_std_mm[ok] ** 2)) - run.ratio_error_mm**2,
                        1e-12) / run.noise_scale)
    if abs(run.ratio_offset_mm) <= RATIO_SIGMAS * own:
        return None
    return (f"in free rolling the filter's radius sits {run.ratio_offset_mm:+.2f} mm from the"
            f" speed-ratio radius {ratio_mm:.2f} mm ({abs(run.ratio_offset_mm) / own:.0f}x its"
            " own spread): the model's free-rolling forces (the roller motor's torque at this"
            " supply frequency, bearing drag) do not hold on this session, and the same model"
            f" carries the traction phases; the bands admit it (±{run.ratio_error_mm:.2f} mm,"
            " 1σ). Check --supply-hz, the rig datasheet and the speeds' units; the"
            " speed-ratio radius is the free-rolling answer")


def _supply(
    session: Session,
    opts: RollerRigOptions,
    spec: RollerRigSpec,
    w_w: np.ndarray,
    w_r: np.ndarray,
    free: np.ndarray,
) -> tuple[float, str]:
    if opts.supply_hz is not None:
        return float(opts.supply_hz), "option --supply-hz"
    key = next((k for k in SUPPLY_FACTS if k in session.metadata), SUPPLY_FACT)
    fact = session.metadata.get(key)
    if fact is not None:
        try:
            value = float(fact)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            raise DataError(
                f"session fact {key}={fact!r} is not a frequency in Hz;"
                " fix it or pass --supply-hz",
                path=session.path,
            )
        return value, f"session fact {key}"
    return infer_supply_hz(spec, w_w, w_r, free), "inferred from free rolling"


def _phase_mean(x_mm: np.ndarray, mask: np.ndarray) -> float | None:
    v = x_mm[mask & np.isfinite(x_mm)]
    return float(np.mean(v)) if v.size else None


def naive_radius_mm(result: RollerRigResult, mask: np.ndarray) -> float | None:
    """Speed-ratio radius sum(omega_r) R_r / sum(omega_w) over a phase, mm.

    A ratio of sums, not a median or mean of per-sample ratios: the encoders' speeds
    are quantised to a few counts per sample, and a statistic of the quantised ratio
    is biased by the quantisation grid.
    """
    ok = mask & np.isfinite(result.omega_w) & np.isfinite(result.omega_r)
    if not ok.any():
        return None
    return float(
        np.sum(result.omega_r[ok]) * result.spec.roller_radius / np.sum(result.omega_w[ok]) * 1e3
    )


def _convergence_why(run: GuessRun) -> str | None:
    """Why a guess's ``convergence_time_s`` is null (None when it is a time)."""
    if run.restart:
        return ("re-started from the free-rolling ratio radius (see restarted): the filter"
                " from r0 did not converge")
    if run.convergence_time_s is None:
        return (f"the forward filter's {CONVERGENCE_WINDOW_S:g} s means do not stay within"
                f" {CONVERGED_MM:g} mm of its end value")
    return None


def _summary(result: RollerRigResult, warnings: list[str], elapsed: float) -> dict[str, Any]:
    ref = result.reference_mm
    runs = []
    for run in result.runs:
        err = None if ref is None else rmse(run.radius_mm, ref)
        err_f = None if ref is None else rmse(run.filter_mm, ref)
        after = None
        if ref is not None and run.convergence_time_s is not None:
            tail = result.time - result.time[0] >= run.convergence_time_s
            after = float(np.max(np.abs(run.radius_mm[tail] - ref)))
        runs.append(
            {
                "r0_mm": run.r0_mm,
                "restarted": run.restart,
                "radius_mm": float(run.radius_mm[-1]),
                "radius_std_mm": float(run.radius_std_mm[-1]),
                "creep_model_error_mm_per_knm": run.model_error_mm_per_knm,
                "free_rolling_offset_from_ratio_mm": run.ratio_offset_mm,
                "ratio_model_error_mm": run.ratio_error_mm,
                "consistency": run.consistency,
                "noise_scale": run.noise_scale,
                # a re-started guess's filter ran from the ratio radius, where it is at 0 s:
                # no time from r0 exists (null, OUTPUTS.md), and the reason is given
                "convergence_time_s": None if run.restart else run.convergence_time_s,
                "convergence_time_why": _convergence_why(run),
                "rmse_vs_ref_mm": err,
                "rmse_vs_ref_pct": None if ref is None else 100.0 * err / ref,
                "filter_rmse_vs_ref_mm": err_f,
                "filter_rmse_vs_ref_pct": None if ref is None else 100.0 * err_f / ref,
                "max_error_after_convergence_mm": after,
                "traction_radius_mm": _phase_mean(run.radius_mm, result.traction),
            }
        )
    naive_free = naive_radius_mm(result, result.free)
    naive_trac = naive_radius_mm(result, result.traction)
    ukf_trac = runs[0]["traction_radius_mm"]
    comparison: dict[str, Any] = {
        "naive_free_mm": naive_free, "naive_traction_mm": naive_trac,
        "ukf_traction_mm": ukf_trac,
        "naive_traction_drop_mm": (None if naive_free is None or naive_trac is None
                                   else naive_free - naive_trac),
    }  # fmt: skip
    if ref is not None:
        comparison["naive_traction_error_mm"] = None if naive_trac is None else naive_trac - ref
        comparison["ukf_traction_error_mm"] = None if ukf_trac is None else ukf_trac - ref
        comparison["naive_free_error_mm"] = None if naive_free is None else naive_free - ref
    return {
        "session": str(result.session.path),
        "rig": result.spec.id,
        "rate_hz": result.session.rate_hz,
        "duration_s": float(result.time[-1] - result.time[0]),
        "smoother": result.options.smoother,
        "supply_hz": result.supply_hz,
        "supply_source": result.supply_source,
        "runs": runs,
        "naive_ratio_radius_mm": naive_free,
        "reference_radius_mm": ref,
        "naive_vs_ukf": comparison,
        "traction_share": float(np.mean(result.traction)),
        "filter": {
            "alpha": result.spec.filter.alpha,
            "beta": result.spec.filter.beta,
            "kappa": result.spec.filter.kappa,
            "p0": list(result.spec.filter.p0),
            "q": list(result.spec.filter.q),
            "r": list(result.spec.filter.r),
            "rk4_substep_s": result.spec.filter.substep,
        },
        "warnings": warnings,
        "wall_time_s": elapsed,
    }


UNITS = {"wheel_omega": "rad/s", "roller_omega": "rad/s", "creep_force": "N", "creepage": "-",
         "naive_radius_mm": "mm", "time": "s"}  # fmt: skip


def roller_rig_frame(result: RollerRigResult) -> tuple[pd.DataFrame, dict[str, str]]:
    """The ``roller_rig.parquet`` table (OUTPUTS.md) and its units."""
    cols: dict[str, np.ndarray] = {"time": result.time - result.time[0]}
    units = dict(UNITS)
    for run in result.runs:
        g = guess_label(run.r0_mm)
        cols[f"radius_mm_{g}"] = run.radius_mm
        cols[f"radius_std_mm_{g}"] = run.radius_std_mm
        cols[f"radius_filter_mm_{g}"] = run.filter_mm
        for name in (f"radius_mm_{g}", f"radius_std_mm_{g}", f"radius_filter_mm_{g}"):
            units[name] = "mm"
    st = result.runs[0].states
    cols["wheel_omega"] = st[:, 0]
    cols["roller_omega"] = st[:, 1]
    cols["creep_force"] = result.creep_force
    cols["creepage"] = result.creepage
    cols["naive_radius_mm"] = result.naive_mm
    return pd.DataFrame(cols), units


def write_roller_rig(result: RollerRigResult, out: str | Path) -> Path:
    """Write ``DIR/<stem>/roller_rig.parquet``, ``summary.json`` and the report page."""
    from brakethermo.pipelines.rig_outputs import write_rig_outputs
    from brakethermo.report.roller_rig_page import roller_rig_page

    frame, units = roller_rig_frame(result)
    return write_rig_outputs(
        Path(out), result.stem, PIPELINE, frame, result.summary, roller_rig_page(result), units
    )
